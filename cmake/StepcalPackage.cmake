# Debian packages by CPack (`cpack -G DEB` in the build folder; docs/install.md):
#   stepcal        the executables, the robots' URDFs, the LCM types, the daemon as a systemd
#                  service (stepcal-runtime@.service, /etc/stepcal/cell1.conf, the `stepcal` system
#                  user, /var/lib/stepcal for models), the user's documentation
#   stepcal-dev    the static libraries, headers, CMake package and pkg-config file
#   python3-stepcal  the Python module (when STEPCAL_BUILD_PYTHON)
# Run-time dependencies are computed from the executables' shared libraries (dpkg-shlibdeps); the
# development package depends on the Debian -dev packages its static libraries need at link time.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME stepcal)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "stepcal")
set(STEPCAL_DEB_MAINTAINER "stepcal developers <stepcal@localhost>" CACHE STRING
  "Maintainer field of the Debian packages")
set(CPACK_PACKAGE_CONTACT "${STEPCAL_DEB_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${STEPCAL_DEB_MAINTAINER}")
set(CPACK_PACKAGE_HOMEPAGE_URL "")
# Install into the staging root with DESTDIR and the prefix /usr, so that the install rules see
# the real prefix (the daemon's files go to /etc and /lib/systemd/system; StepcalInstall.cmake).
set(CPACK_SET_DESTDIR ON)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL stepcal dev)
if(STEPCAL_BUILD_PYTHON)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS OFF)

set(CPACK_DEBIAN_STEPCAL_PACKAGE_NAME stepcal)
set(CPACK_DEBIAN_STEPCAL_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_STEPCAL_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_STEPCAL_PACKAGE_SUGGESTS "stepcal-dev, python3-stepcal")
# Descriptions: the first line is the synopsis; CPack indents the others (at most 80 columns).
set(CPACK_DEBIAN_STEPCAL_DESCRIPTION "stepwise calibration of heavy-duty serial robots
The stepcal command calibrates a robot from a measurement campaign (geometry
with a local product-of-exponentials model, joint compliance, a Gaussian
process on the residual), diagnoses what the physical model gets wrong, and
writes one binary model file. The daemon stepcal-runtime corrects commanded
poses and inverts desired poses with that model over LCM, the wrench read live
from an F/T sensor on CAN; it runs as the systemd service stepcal-runtime@CELL,
configured in /etc/stepcal/CELL.conf, as user stepcal. The cell key, if any, is
/etc/stepcal/CELL.key, root:root 0600: systemd reads it and hands it to the
daemon as the credential cell-key.")
set(CPACK_DEBIAN_STEPCAL_PACKAGE_CONTROL_EXTRA
  ${PROJECT_SOURCE_DIR}/cmake/debian/postinst ${PROJECT_SOURCE_DIR}/cmake/debian/prerm
  ${PROJECT_SOURCE_DIR}/cmake/debian/postrm ${PROJECT_SOURCE_DIR}/cmake/debian/conffiles)

set(CPACK_DEBIAN_DEV_PACKAGE_NAME stepcal-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(stepcal_dev_depends "libeigen3-dev (>= 3.4)" "liblcm-dev" "libsodium-dev")
if(STEPCAL_BUILD_TRAINER)
  list(APPEND stepcal_dev_depends libyaml-cpp-dev liburdfdom-dev libtinyxml-dev pkg-config)
endif()
string(JOIN ", " CPACK_DEBIAN_DEV_PACKAGE_DEPENDS ${stepcal_dev_depends})
set(CPACK_DEBIAN_DEV_DESCRIPTION "stepwise calibration of heavy-duty robots - development files
The static libraries (position-independent code) and headers of stepcal: the
real-time runtime (stepcal::runtime: correctForward, solveInverse with a model
file, in process), the daemon's service and LCM types, the trainer; the CMake
package (find_package(stepcal COMPONENTS runtime)) and the pkg-config file
stepcal-runtime.")

set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-stepcal)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
set(CPACK_DEBIAN_PYTHON_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "python3 (>= ${STEPCAL_PYTHON_VERSION}), python3 (<< ${STEPCAL_PYTHON_NEXT_VERSION}), python3-numpy")
set(CPACK_DEBIAN_PYTHON_DESCRIPTION "stepwise calibration of heavy-duty robots - Python module
The Python module stepcal: campaigns, calibration and diagnosis with their
results as numpy arrays, model files, the runtime's forward correction and
inverse vectorised over numpy arrays, and requests to the stepcal-runtime
daemon over LCM through LCM's C library.")
include(CPack)
