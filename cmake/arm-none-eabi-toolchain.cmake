# Toolchain file for the Raspberry Pi Pico's RP2040 (Cortex-M0+) with Debian's gcc-arm-none-eabi,
# libnewlib-arm-none-eabi and libstdc++-arm-none-eabi-newlib (scripts/setup.sh installs them).
# Use: cmake -S firmware/platform/pico -B build/pico \
#        -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-toolchain.cmake
# (the native build does this itself through ExternalProject; see firmware/CMakeLists.txt).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
find_program(ARM_SIZE arm-none-eabi-size REQUIRED)
find_program(ARM_OBJCOPY arm-none-eabi-objcopy REQUIRED)

set(JA_ARM_CPU_FLAGS "-mcpu=cortex-m0plus -mthumb")
# Unused functions and data are dropped at link time (--gc-sections below).
set(JA_ARM_SECTION_FLAGS "-ffunction-sections -fdata-sections")
set(CMAKE_C_FLAGS_INIT "${JA_ARM_CPU_FLAGS} ${JA_ARM_SECTION_FLAGS}")
set(CMAKE_CXX_FLAGS_INIT
    "${JA_ARM_CPU_FLAGS} ${JA_ARM_SECTION_FLAGS} -fno-exceptions -fno-rtti -fno-threadsafe-statics")
set(CMAKE_ASM_FLAGS_INIT "${JA_ARM_CPU_FLAGS}")

# newlib-nano (smaller memcpy/printf family) when its multilib for v6-M is installed.
execute_process(COMMAND arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb -print-file-name=libc_nano.a
                OUTPUT_VARIABLE ja_libc_nano OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
set(JA_ARM_SPECS "")
if(IS_ABSOLUTE "${ja_libc_nano}" AND EXISTS "${ja_libc_nano}")
  set(JA_ARM_SPECS "--specs=nano.specs")
endif()
set(CMAKE_EXE_LINKER_FLAGS_INIT "${JA_ARM_CPU_FLAGS} -Wl,--gc-sections ${JA_ARM_SPECS}")
set(CMAKE_EXECUTABLE_SUFFIX .elf)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
