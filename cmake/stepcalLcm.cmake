# The LCM C library as the imported target lcm::lcm (the name of LCM's own CMake package, which
# Debian's liblcm-dev does not ship: it has lcm.pc, whose Requires: glib-2.0 needs glib's
# development files that LCM's headers never include, so header and library are found directly).
# Used by the build and by the installed stepcalConfig.cmake. Sets stepcal_lcm_FOUND.
if(TARGET lcm::lcm)
  set(stepcal_lcm_FOUND TRUE)
  return()
endif()
find_path(STEPCAL_LCM_INCLUDE_DIR lcm/lcm.h)
find_library(STEPCAL_LCM_LIBRARY lcm)
if(STEPCAL_LCM_INCLUDE_DIR AND STEPCAL_LCM_LIBRARY)
  add_library(lcm::lcm UNKNOWN IMPORTED)
  set_target_properties(lcm::lcm PROPERTIES
    IMPORTED_LOCATION "${STEPCAL_LCM_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${STEPCAL_LCM_INCLUDE_DIR}")
  set(stepcal_lcm_FOUND TRUE)
else()
  set(stepcal_lcm_FOUND FALSE)
endif()
