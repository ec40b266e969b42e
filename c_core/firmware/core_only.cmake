# Link the core library alone for the target, for scripts/fw_report.py's flash figures.
# Roots (-u): every global symbol the archive defines, or, with ROOTS_HEADER, the functions
# that header declares (mca_nav.h: what a flight controller calls). --gc-sections drops
# the rest; libm/libc/libgcc members come in only as the roots need them.
# Run by CMakeLists.txt (cmake -P) with NM, CC, FLAGS, LDSCRIPT, ARCHIVE, OUTPUT [, ROOTS_HEADER].
set(_names)
if(ROOTS_HEADER)
    file(READ ${ROOTS_HEADER} _hdr)
    string(REGEX MATCHALL "(mca_[a-z0-9_]+)\\(" _decls "${_hdr}")
    foreach(_d IN LISTS _decls)
        string(REPLACE "(" "" _name "${_d}")
        list(APPEND _names ${_name})
    endforeach()
else()
    execute_process(COMMAND ${NM} -g --defined-only ${ARCHIVE} OUTPUT_VARIABLE _syms RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "${NM} failed on ${ARCHIVE}")
    endif()
    string(REGEX MATCHALL "[0-9a-fA-F]+ [TDRB] [A-Za-z_][A-Za-z0-9_]*" _defs "${_syms}")
    foreach(_d IN LISTS _defs)
        string(REGEX REPLACE "^[0-9a-fA-F]+ [TDRB] " "" _name "${_d}")
        list(APPEND _names ${_name})
    endforeach()
endif()
list(REMOVE_DUPLICATES _names)
if(NOT _names)
    message(FATAL_ERROR "no roots for ${OUTPUT}")
endif()
set(_roots)
foreach(_name IN LISTS _names)
    list(APPEND _roots "-Wl,-u,${_name}")
endforeach()
execute_process(
    COMMAND ${CC} ${FLAGS} -nostartfiles -Wl,--entry=0 -T ${LDSCRIPT} ${_roots} ${ARCHIVE} -lm -o ${OUTPUT}
    RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "linking the core alone failed")
endif()
