# cmake -P script for the test schema.reproduce_paper: runs reproduce-paper on seed 1 and
# validates its JSON. Inputs: ANALYZE, PYTHON, SCHEMA_DIR, OUT.
execute_process(COMMAND ${ANALYZE} reproduce-paper --seeds 1 --json ${OUT} RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "reproduce-paper failed (${rc})")
endif()
execute_process(COMMAND ${PYTHON} ${SCHEMA_DIR}/validate_json.py ${SCHEMA_DIR}/reproduce-paper.schema.json ${OUT}
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${OUT} does not follow reproduce-paper.schema.json")
endif()
