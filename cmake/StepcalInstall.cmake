# Install rules and the CMake package (docs/install.md): the libraries as the exported targets
# stepcal::common, common_io, runtime, service, lcmtypes, trainer (export set stepcalTargets), their
# headers, the generated LCM headers and the .lcm files, the executables, the robots' URDFs,
# stepcalConfig.cmake with its version file (components), the runtime's pkg-config file, and the
# daemon's systemd unit and configuration.
#
# Install components: `stepcal` (executables, data, the daemon's unit and configuration), `dev`
# (libraries, headers, CMake and pkg-config files), `python` (python/). CPack makes one Debian
# package of each (cmake/StepcalPackage.cmake).
include(CMakePackageConfigHelpers)
set(STEPCAL_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/stepcal)

# ---- libraries and headers --------------------------------------------------------------------
set(stepcal_libraries stepcal_common stepcal_runtime stepcal_service stepcal_lcmtypes)
set(stepcal_components common runtime service)
if(STEPCAL_BUILD_TRAINER)
  list(APPEND stepcal_libraries stepcal_common_io stepcal_trainer)
  list(APPEND stepcal_components common_io trainer)
endif()
install(TARGETS ${stepcal_libraries} EXPORT stepcalTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

# common's headers of campaign and URDF I/O belong to common_io, built with the trainer.
set(common_io_headers campaign.hpp urdf.hpp urdf_export.hpp)
if(STEPCAL_BUILD_TRAINER)
  install(DIRECTORY common/include/ trainer/include/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev)
else()
  set(exclude)
  foreach(header IN LISTS common_io_headers)
    list(APPEND exclude PATTERN ${header} EXCLUDE)
  endforeach()
  install(DIRECTORY common/include/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev ${exclude})
endif()
install(DIRECTORY runtime/include/ runtime/service/include/
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev)
install(DIRECTORY ${PROJECT_BINARY_DIR}/lcmtypes/include/stepcal_lcm
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev)
install(DIRECTORY lcmtypes/ DESTINATION ${STEPCAL_INSTALL_DATADIR}/lcmtypes COMPONENT dev
        FILES_MATCHING PATTERN "*.lcm")

# ---- the CMake package and the pkg-config file --------------------------------------------------
install(EXPORT stepcalTargets NAMESPACE stepcal:: DESTINATION ${STEPCAL_CMAKE_DIR} COMPONENT dev)
configure_package_config_file(cmake/stepcalConfig.cmake.in
  ${PROJECT_BINARY_DIR}/stepcalConfig.cmake INSTALL_DESTINATION ${STEPCAL_CMAKE_DIR})
# 0.x: a minor release may change the API, so 0.1 is compatible with 0.1.y only.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/stepcalConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/stepcalConfig.cmake
              ${PROJECT_BINARY_DIR}/stepcalConfigVersion.cmake cmake/stepcalLcm.cmake
        DESTINATION ${STEPCAL_CMAKE_DIR} COMPONENT dev)
# pkg-config: the runtime (and common), what an in-process controller links.
file(RELATIVE_PATH STEPCAL_PC_TO_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
string(REGEX REPLACE "/$" "" STEPCAL_PC_TO_PREFIX "${STEPCAL_PC_TO_PREFIX}")
configure_file(cmake/stepcal-runtime.pc.in ${PROJECT_BINARY_DIR}/stepcal-runtime.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/stepcal-runtime.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)

# ---- executables and data -------------------------------------------------------------------------
set(stepcal_executables stepcal-runtime)
if(STEPCAL_BUILD_TOOLS)
  list(APPEND stepcal_executables stepcal stepcal-client stepcal-ftsim stepcal-bench)
endif()
install(TARGETS ${stepcal_executables} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT stepcal)
install(DIRECTORY robots/ DESTINATION ${STEPCAL_INSTALL_DATADIR}/robots COMPONENT stepcal
        FILES_MATCHING PATTERN "*.urdf")

# The daemon as a service: the systemd template unit stepcal-runtime@.service (one instance per
# robot cell) and the configuration of instance cell1, every option at its default
# (stepcal-runtime --print-config, so that a new option shows there by itself), and the model
# folder. Installed into the system's /etc and /lib/systemd/system when the prefix is /usr (the
# Debian package), else under the prefix.
set(STEPCAL_MODEL_DIR /var/lib/stepcal)
set(cell1_conf ${PROJECT_BINARY_DIR}/stepcal-runtime/cell1.conf)
file(MAKE_DIRECTORY ${PROJECT_BINARY_DIR}/stepcal-runtime)
add_custom_command(OUTPUT ${cell1_conf}
  COMMAND $<TARGET_FILE:stepcal-runtime> --print-config --model ${STEPCAL_MODEL_DIR}/cell1.stepcal
          > ${cell1_conf}
  DEPENDS stepcal-runtime
  COMMENT "stepcal-runtime --print-config: cell1.conf")
add_custom_target(stepcal_runtime_conf ALL DEPENDS ${cell1_conf})
install(CODE "
  if(CMAKE_INSTALL_PREFIX STREQUAL \"/usr\")
    set(STEPCAL_ETC /etc/stepcal)
    set(stepcal_units /lib/systemd/system)
    set(STEPCAL_MODELS ${STEPCAL_MODEL_DIR})
  else()
    set(STEPCAL_ETC \"\${CMAKE_INSTALL_PREFIX}/etc/stepcal\")
    set(stepcal_units \"\${CMAKE_INSTALL_PREFIX}/lib/systemd/system\")
    set(STEPCAL_MODELS \"\${CMAKE_INSTALL_PREFIX}${STEPCAL_MODEL_DIR}\")
  endif()
  set(STEPCAL_BIN \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}\")
  set(STEPCAL_DOC \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_DOCDIR}\")
  configure_file(\"${PROJECT_SOURCE_DIR}/runtime/service/stepcal-runtime@.service.in\"
    \"${PROJECT_BINARY_DIR}/stepcal-runtime/stepcal-runtime@.service\" @ONLY)
  file(INSTALL \"${cell1_conf}\" DESTINATION \"\${STEPCAL_ETC}\"
       PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
  file(INSTALL \"${PROJECT_BINARY_DIR}/stepcal-runtime/stepcal-runtime@.service\"
       DESTINATION \"\${stepcal_units}\" PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
  file(MAKE_DIRECTORY \"\$ENV{DESTDIR}\${STEPCAL_MODELS}\")
" COMPONENT stepcal)
# The user's documentation, laid out as in the source tree so that README's links (docs/…,
# docs/img/…) and the docs' own (../README.md) resolve; and the Debian copyright file.
install(FILES README.md cmake/debian/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT stepcal)
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs COMPONENT stepcal
        FILES_MATCHING PATTERN "*.md" PATTERN "img/*")
install(FILES cmake/debian/copyright DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/stepcal-dev
        COMPONENT dev)
