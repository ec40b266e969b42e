# Link the core library alone for the target, for scripts/fw_report.py's flash figures.
# Roots (-u): every global symbol the archive defines, or, with ROOTS_HEADER, the functions
# that header declares (mca_nav.h: what a flight controller calls). --gc-sections drops
# the rest; libm/libc/libgcc members come in only as the roots need them.
# Run by CMakeLists.txt (cmake -P) with NM, CC, FLAGS, LDSCRIPT, ARCHIVE, OUTPUT [, ROOTS_HEADER, LTO].
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
# With LTO (LTO = the firmware's LTO link options): the stack usage of the generated code goes
# next to the image (<image without .elf>.ltrans0.ltrans.su). Without LTO (fat LTO objects in
# the archive), -fno-lto links their ordinary code.
#
# The library functions that only the LTO code generator calls (memset and memcpy for struct
# copies and zeroing, libgcc's 64-bit helpers) are not in the IR's symbol table, and when the
# image's other code does not call them too (the replay program does; a core-alone image has no
# other code), ld has searched libc and libgcc before they are needed. So an LTO link that
# fails on undefined references is repeated once with exactly those symbols as roots: the
# members the generated code calls, nothing more.
set(_lto -fno-lto)
if(LTO)
    string(REGEX REPLACE "\\.elf$" "." _dump "${OUTPUT}")
    set(_lto ${LTO} -dumpdir ${_dump})
endif()
set(_extra)
foreach(_attempt 1 2)
    execute_process(
        COMMAND ${CC} ${FLAGS} ${_lto} -nostartfiles -Wl,--entry=0 -T ${LDSCRIPT} ${_roots} ${_extra} ${ARCHIVE}
                -lm -o ${OUTPUT}
        RESULT_VARIABLE _rc ERROR_VARIABLE _err)
    if(_rc EQUAL 0 OR NOT LTO OR _extra)
        break()
    endif()
    string(REGEX MATCHALL "undefined reference to `[A-Za-z0-9_]+'" _undef "${_err}")
    foreach(_u IN LISTS _undef)
        string(REGEX REPLACE "undefined reference to `([A-Za-z0-9_]+)'" "\\1" _sym "${_u}")
        list(APPEND _extra "-Wl,-u,${_sym}")
    endforeach()
    list(REMOVE_DUPLICATES _extra)
    if(NOT _extra)
        break()
    endif()
endforeach()
if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "linking the core alone failed:\n${_err}")
endif()
