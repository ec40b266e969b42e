# Toolchain: bare-metal Cortex-M4F (arm-none-eabi-gcc, newlib-nano, hard float).
#
#   cmake -S c_core/firmware -B build/fw -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-cortex-m4f.cmake
#
# Every C and assembler file is built for the M4F FPU with the hard-float ABI, each
# function and object in its own section so the linker can drop what nothing references
# (--gc-sections), and with -fstack-usage (a .su file per object, read by
# scripts/fw_report.py). Every executable gets a map file next to it (<elf>.map).
# c_core/firmware/CMakeLists.txt adds link-time optimisation on top (MCA_FW_LTO).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# gcc-ar/gcc-ranlib load the LTO plugin, so an archive of LTO objects gets a symbol index
# (c_core/firmware links with -flto); on plain objects they are ar and ranlib.
set(CMAKE_AR arm-none-eabi-gcc-ar)
set(CMAKE_RANLIB arm-none-eabi-gcc-ranlib)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy)
set(CMAKE_OBJDUMP arm-none-eabi-objdump)
set(CMAKE_SIZE arm-none-eabi-size)
set(CMAKE_NM arm-none-eabi-nm)

# The compiler check links a test program; without startup code and a linker script that
# cannot succeed, so check by building a static library instead.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(MCA_M4F_CPU_FLAGS "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT "${MCA_M4F_CPU_FLAGS} -ffunction-sections -fdata-sections -fstack-usage")
set(CMAKE_ASM_FLAGS_INIT "${MCA_M4F_CPU_FLAGS}")
# "%" is replaced by the output file's path (binutils >= 2.38): fw.elf -> fw.elf.map.
set(CMAKE_EXE_LINKER_FLAGS_INIT
    "${MCA_M4F_CPU_FLAGS} --specs=nano.specs -Wl,--gc-sections -Wl,-Map=%.map -Wl,--print-memory-usage")

# Optimisation of the firmware build types (MinSizeRel -Os, the firmware; Release -O2). CMake
# appends its defaults to these (-O3 -DNDEBUG after -O2), so c_core/firmware/CMakeLists.txt sets
# the build types' flags outright; these are for other projects that use this toolchain file.
set(CMAKE_C_FLAGS_RELEASE_INIT "-O2")
set(CMAKE_C_FLAGS_MINSIZEREL_INIT "-Os")
set(CMAKE_C_FLAGS_RELWITHDEBINFO_INIT "-O2 -g")

# Look for libraries and headers in the target environment only, programs on the host.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
