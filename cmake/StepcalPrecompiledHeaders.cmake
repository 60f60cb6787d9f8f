# Precompiled headers: Eigen and the large standard headers parsed once per library instead of
# once per source file. Each of the ~110 files the `stepcal` command is built from spends about
# 1 s of CPU parsing them (most files are small: the parse is the larger part of their compile);
# figures in docs/install.md, "Building". The code generated is the same (same flags).
#
# Default ON, except where the compiler launcher is ccache: ccache hits a precompiled header only
# with CCACHE_SLOPPINESS=pch_defines,time_macros (else it runs the compiler every time), so a
# developer's ccache build keeps its hits unless it asks for both:
#   CCACHE_SLOPPINESS=pch_defines,time_macros cmake -DSTEPCAL_PRECOMPILED_HEADERS=ON ...
if(CMAKE_CXX_COMPILER_LAUNCHER MATCHES "ccache")
  set(stepcal_pch_default OFF)
else()
  set(stepcal_pch_default ON)
endif()
option(STEPCAL_PRECOMPILED_HEADERS
  "precompiled Eigen and standard headers for the libraries and the stepcal command"
  ${stepcal_pch_default})

# The headers nearly every file of the libraries includes (directly or through stepcal's own);
# a file must still include what it uses (the build without precompiled headers checks it).
set(STEPCAL_PRECOMPILED_HEADERS_LIST
  <Eigen/Dense> <algorithm> <array> <cmath> <functional> <map> <memory> <optional>
  <sstream> <string> <utility> <vector>)

# The libraries share one precompiled header, stepcal_common's (same flags: -fPIC, Eigen's
# alignment; a library's own definitions such as STEPCAL_VERSION do not appear in it): its cost,
# ~5 s, is paid once instead of once per library. An executable (-fPIE) has its own, with the
# extra headers its files include (the stepcal command: CLI11, nlohmann-json).
function(stepcal_precompile_headers target)
  if(NOT STEPCAL_PRECOMPILED_HEADERS)
    return()
  endif()
  if(target STREQUAL "stepcal_common" OR ARGN)
    target_precompile_headers(${target} PRIVATE ${STEPCAL_PRECOMPILED_HEADERS_LIST} ${ARGN})
  else()
    target_precompile_headers(${target} REUSE_FROM stepcal_common)
  endif()
endfunction()
