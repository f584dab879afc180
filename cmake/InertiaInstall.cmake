# Install rules (`cmake --install`) for the bench PC, and the pieces only an install has: the
# lcm-spy launcher pointing at installed paths and the man pages. The Debian package
# (cmake/InertiaPackage.cmake) is these rules run under /usr.
#
#   bin/inertia-daqd, bin/inertia-analyze
#   lib/systemd/system/inertia-daqd.service   (ExecStart rewritten to this prefix's bin/)
#   lib/sysusers.d/inertia.conf, lib/tmpfiles.d/inertia.conf
#   share/inertia/config/*.toml               (the bench template and the simulated benches)
#   share/inertia/inertia-lcm-spy, share/inertia/inertia_lcm_types.jar
#   share/doc/inertia/README.md, README.daq.md, docs/ (the pages the README links), copyright
#   share/man/man1/inertia-daqd.1.gz, inertia-analyze.1.gz   (help2man, when installed)
#   /etc/inertia/bench.toml                   (the template; never overwritten once there)

set(INERTIA_DATA_DIR share/inertia)
set(INERTIA_DOC_DIR share/doc/inertia)

install(TARGETS inertia-daqd inertia-analyze RUNTIME DESTINATION bin)

# The unit runs the daemon from wherever this install puts it: /usr/bin in the package.
install(CODE "
  file(READ \"${PROJECT_SOURCE_DIR}/systemd/inertia-daqd.service\" unit)
  string(REPLACE \"/usr/bin/inertia-daqd\" \"\${CMAKE_INSTALL_PREFIX}/bin/inertia-daqd\" unit \"\${unit}\")
  file(WRITE \"${PROJECT_BINARY_DIR}/install/inertia-daqd.service\" \"\${unit}\")")
install(FILES ${PROJECT_BINARY_DIR}/install/inertia-daqd.service DESTINATION lib/systemd/system)
install(FILES systemd/inertia.sysusers DESTINATION lib/sysusers.d RENAME inertia.conf)
install(FILES systemd/inertia.tmpfiles DESTINATION lib/tmpfiles.d RENAME inertia.conf)

file(GLOB _configs CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/config/*.toml)
install(FILES ${_configs} DESTINATION ${INERTIA_DATA_DIR}/config)
# /etc/inertia/bench.toml is the bench's own file once a technician has edited it: an install
# over an existing one leaves it alone (the package marks it a conffile, dpkg keeps it too).
install(CODE "
  set(bench \"\$ENV{DESTDIR}/etc/inertia/bench.toml\")
  if(EXISTS \"\${bench}\")
    message(STATUS \"Kept: \${bench} (a bench file is never overwritten)\")
  else()
    # file(INSTALL) puts DESTDIR (the package's staging tree) in front of /etc itself.
    file(INSTALL \"${PROJECT_SOURCE_DIR}/config/bench-template.toml\" DESTINATION /etc/inertia
         RENAME bench.toml PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ)
  endif()")

# lcm-spy launcher: the same script as build/bin/inertia-lcm-spy, its jar where the install puts it.
set(_jchart2d_jar ${JCHART2D_JAR})
if(NOT _jchart2d_jar)
  set(_jchart2d_jar /usr/share/java/jchart2d.jar)  # where libjchart2d-java puts it (a Recommends)
endif()
install(FILES ${INERTIA_LCM_TYPES_JAR} DESTINATION ${INERTIA_DATA_DIR})
install(CODE "
  file(READ \"${PROJECT_SOURCE_DIR}/common/lcm/inertia-lcm-spy.in\" launcher)
  string(REPLACE \"@LCM_JAR@\" \"${LCM_JAR}\" launcher \"\${launcher}\")
  string(REPLACE \"@JCHART2D_JAR@\" \"${_jchart2d_jar}\" launcher \"\${launcher}\")
  string(REPLACE \"@INERTIA_LCM_TYPES_JAR@\" \"\${CMAKE_INSTALL_PREFIX}/${INERTIA_DATA_DIR}/inertia_lcm_types.jar\" launcher \"\${launcher}\")
  string(REPLACE \"build it: cmake --build @PROJECT_BINARY_DIR@ --target inertia_lcm_types\" \"reinstall the inertia package\" launcher \"\${launcher}\")
  file(WRITE \"${PROJECT_BINARY_DIR}/install/inertia-lcm-spy\" \"\${launcher}\")")
install(PROGRAMS ${PROJECT_BINARY_DIR}/install/inertia-lcm-spy DESTINATION ${INERTIA_DATA_DIR})

install(FILES README.md DESTINATION ${INERTIA_DOC_DIR})
install(FILES daq/README.md DESTINATION ${INERTIA_DOC_DIR} RENAME README.daq.md)
# The README's links point into docs/: the pages travel with it.
install(DIRECTORY docs/ DESTINATION ${INERTIA_DOC_DIR}/docs FILES_MATCHING PATTERN "*.md" PATTERN "*.png")
install(FILES cmake/debian/copyright DESTINATION ${INERTIA_DOC_DIR})

# Man pages from --help (help2man), so they never drift from the options the binaries take.
find_program(HELP2MAN help2man)
if(HELP2MAN)
  set(_man_dir ${PROJECT_BINARY_DIR}/man)
  add_custom_command(
    OUTPUT ${_man_dir}/inertia-daqd.1.gz ${_man_dir}/inertia-analyze.1.gz
    COMMAND ${CMAKE_COMMAND} -DHELP2MAN=${HELP2MAN} -DVERSION=${PROJECT_VERSION} -DOUT=${_man_dir}
            -DDAQD=$<TARGET_FILE:inertia-daqd> -DANALYZE=$<TARGET_FILE:inertia-analyze>
            -DINCLUDES=${PROJECT_SOURCE_DIR}/cmake/man -P ${PROJECT_SOURCE_DIR}/cmake/InertiaManPages.cmake
    DEPENDS inertia-daqd inertia-analyze ${PROJECT_SOURCE_DIR}/cmake/InertiaManPages.cmake
            ${PROJECT_SOURCE_DIR}/cmake/man/inertia-daqd.h2m ${PROJECT_SOURCE_DIR}/cmake/man/inertia-analyze.h2m
    COMMENT "help2man: man pages of inertia-daqd and inertia-analyze"
    VERBATIM)
  add_custom_target(inertia_man ALL DEPENDS ${_man_dir}/inertia-daqd.1.gz ${_man_dir}/inertia-analyze.1.gz)
  install(FILES ${_man_dir}/inertia-daqd.1.gz ${_man_dir}/inertia-analyze.1.gz DESTINATION share/man/man1)
else()
  message(STATUS "help2man not found: no man pages (apt-get install help2man)")
endif()
