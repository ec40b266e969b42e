# Link the core library alone for the target: every global symbol the archive defines is a
# root (-u), --gc-sections drops the rest, libm/libc members come in only as the core
# needs them. Run by CMakeLists.txt (cmake -P) with NM, CC, FLAGS, LDSCRIPT, ARCHIVE, OUTPUT.
execute_process(COMMAND ${NM} -g --defined-only ${ARCHIVE} OUTPUT_VARIABLE _syms RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "${NM} failed on ${ARCHIVE}")
endif()
string(REGEX MATCHALL "[0-9a-fA-F]+ [TDRB] [A-Za-z_][A-Za-z0-9_]*" _defs "${_syms}")
set(_roots)
foreach(_d IN LISTS _defs)
    string(REGEX REPLACE "^[0-9a-fA-F]+ [TDRB] " "" _name "${_d}")
    list(APPEND _roots "-Wl,-u,${_name}")
endforeach()
execute_process(
    COMMAND ${CC} ${FLAGS} -nostartfiles -Wl,--entry=0 -T ${LDSCRIPT} ${_roots} ${ARCHIVE} -lm -o ${OUTPUT}
    RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "linking the core alone failed")
endif()
