# The Debian binary package, inertia_<version>_amd64.deb: CPack's DEB generator over
# the install rules of cmake/InertiaInstall.cmake, under /usr.
#   cmake --build build --target package      (or: cd build && cpack -G DEB)
#
# Why CPack and not native Debian packaging (debian/ + dpkg-buildpackage): the package is built
# from the build tree the tests ran on, by the same CMake that knows every file it installs, in
# one command and without debhelper, a source package or a changelog to keep in step. What
# debhelper would add is written out here instead: the shared-library dependencies
# (dpkg-shlibdeps, CPACK_DEBIAN_PACKAGE_SHLIBDEPS), the conffile, and the maintainer scripts in
# cmake/debian/ (user, state directory, no service start before the bench file is edited).
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME inertia)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "inertial-sensor test bench: acquisition daemon and analyzer")
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "inertia-daqd samples a bench's CAN, GPIO and Modbus (TCP and RTU) devices as a hardened
systemd service, publishes the samples on LCM and keeps a durable event log;
inertia-daqd --check says which configured device is missing or miswired.
inertia-analyze identifies one nonlinear dynamic model per inertial sensor
from rotation-table, shaker and thermal tests, offline or live.")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)        # inertia_<version>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "inertia maintainers <inertia@localhost>")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
# Runtime libraries as dpkg-shlibdeps finds them in the binaries; plus what no ELF file says:
# systemd (the service; systemd-sysusers and systemd-tmpfiles in postinst) and procps (the
# unit's ExecReload= /bin/kill; a minimal Debian 12 has none).
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "systemd, procps")
# The lcm-spy launcher's Java, LCM's and jchart2d's jars, and gnuplot for the reports' plots:
# wanted on a desktop bench PC, not needed by the daemon (apt installs Recommends by default;
# --no-install-recommends leaves them out on a headless acquisition PC).
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "default-jre, liblcm-java, libjchart2d-java, gnuplot-nox")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${PROJECT_SOURCE_DIR}/cmake/debian/conffiles
    ${PROJECT_SOURCE_DIR}/cmake/debian/postinst
    ${PROJECT_SOURCE_DIR}/cmake/debian/prerm
    ${PROJECT_SOURCE_DIR}/cmake/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# Debug information stays in the build tree; the package carries stripped binaries.
set(CPACK_STRIP_FILES ON)
include(CPack)
