# The one list of C core sources. The host library, the Python extension and the
# Cortex-M4F firmware all build exactly these files.
set(MCA_CORE_SOURCES
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_math.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_robust.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_cs.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_geo.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_att.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_nav.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_profile.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_replay.c
    ${CMAKE_CURRENT_LIST_DIR}/src/mca_ins.c
)
set(MCA_CORE_INCLUDE_DIR ${CMAKE_CURRENT_LIST_DIR}/include)
# Warnings every build of the core uses (the issue's list plus a few that catch float bugs).
set(MCA_C_WARNINGS
    -Wall -Wextra -Werror -Wdouble-promotion -Wconversion -Wshadow -Wfloat-equal -Wvla
    -Wstrict-prototypes -Wmissing-prototypes -pedantic
)
# Same float arithmetic on host and target: no fused multiply-add contraction.
# -fno-math-errno: the core never reads errno, so sqrtf is the FPU's square root inline
# (VSQRT on the M4F) instead of a call into libm's errno wrapper; it changes no value.
set(MCA_C_FLOAT_FLAGS -ffp-contract=off -fno-fast-math -fno-math-errno)
# Code generation, values unchanged: zeroing and copying loops stay loops. GCC otherwise turns
# them into memset/memcpy calls, whose call and alignment set-up cost more on the M4F than the
# 2-36 floats the update loops move (about 40 such calls in every GPS step).
set(MCA_C_CODEGEN_FLAGS -fno-tree-loop-distribute-patterns)
