# cmake -P script (cmake/InertiaInstall.cmake runs it at build time): man pages for
# inertia-daqd and inertia-analyze from their --help, with help2man, gzipped for share/man/man1.
# inertia-analyze's page carries every verb's --help too (CLI11 prints only the verbs' names at
# the top level). Inputs: HELP2MAN, VERSION, OUT, DAQD, ANALYZE, INCLUDES (cmake/man).
file(MAKE_DIRECTORY ${OUT})

# roff: a backslash is an escape, a line starting with . or ' a request.
function(as_roff_text text out)
  string(REPLACE "\\" "\\e" text "${text}")
  string(REGEX REPLACE "(^|\n)([.'])" "\\1\\\\&\\2" text "${text}")
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

execute_process(COMMAND ${ANALYZE} --help OUTPUT_VARIABLE top RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${ANALYZE} --help failed (${rc})")
endif()
string(REGEX REPLACE ".*\nSubcommands:\n" "" listing "${top}")
string(REGEX MATCHALL "(^|\n)  [a-z][a-z-]*" verbs "${listing}")
set(verbs_text "[VERBS]\n")
foreach(v IN LISTS verbs)
  string(STRIP "${v}" verb)
  execute_process(COMMAND ${ANALYZE} ${verb} --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${ANALYZE} ${verb} --help failed (${rc})")
  endif()
  string(REPLACE "${ANALYZE}" "inertia-analyze" help "${help}")  # CLI11 prints argv[0]: the build path
  as_roff_text("${help}" help)
  string(APPEND verbs_text ".SS ${verb}\n.nf\n${help}.fi\n")
endforeach()
file(WRITE ${OUT}/inertia-analyze-verbs.h2m "${verbs_text}")

function(man_page binary name includes)
  get_filename_component(page ${binary} NAME)
  set(include_args)
  foreach(i IN LISTS includes)
    list(APPEND include_args --include=${i})
  endforeach()
  execute_process(
    COMMAND ${HELP2MAN} --no-info --no-discard-stderr --version-string=${VERSION} --name=${name} ${include_args}
            --output=${OUT}/${page}.1 ${binary}
    RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "help2man ${binary} failed (${rc})")
  endif()
  # -n: no name or time stamp in the header, so the page is the same at every build.
  execute_process(COMMAND gzip -9 -n -f ${OUT}/${page}.1 RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "gzip ${OUT}/${page}.1 failed (${rc})")
  endif()
endfunction()

man_page(${DAQD} "acquisition daemon of the inertia inertial-sensor test bench" "${INCLUDES}/inertia-daqd.h2m")
man_page(${ANALYZE} "identify nonlinear dynamic models of inertial sensors"
         "${INCLUDES}/inertia-analyze.h2m;${OUT}/inertia-analyze-verbs.h2m")
