# ctest helper: replay one vector file (REPLAY IN OUT) and compare the output with EXPECT.
execute_process(COMMAND ${REPLAY} ${IN} ${OUT} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${REPLAY} ${IN}: exit ${rc}\n${out}\n${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT} ${EXPECT} RESULT_VARIABLE d)
if(NOT d EQUAL 0)
    message(FATAL_ERROR "${OUT} differs from ${EXPECT}: regenerate with scripts/gen_vectors.py and review")
endif()
