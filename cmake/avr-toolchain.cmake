# Toolchain file for the ATmega2560 (Arduino Mega 2560) with Debian's gcc-avr 5.4 + avr-libc.
# Use: cmake -S firmware/platform/avr -B build/avr -DCMAKE_TOOLCHAIN_FILE=cmake/avr-toolchain.cmake
# (the native build does this itself through ExternalProject; see firmware/CMakeLists.txt).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR avr)
set(CMAKE_C_COMPILER avr-gcc)
set(CMAKE_CXX_COMPILER avr-g++)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
find_program(AVR_SIZE avr-size REQUIRED)
find_program(AVR_OBJCOPY avr-objcopy REQUIRED)

set(JA_AVR_MCU atmega2560 CACHE STRING "avr-gcc -mmcu")
set(JA_AVR_F_CPU 16000000 CACHE STRING "CPU clock in Hz")
set(CMAKE_C_FLAGS_INIT "-mmcu=${JA_AVR_MCU} -DF_CPU=${JA_AVR_F_CPU}UL")
set(CMAKE_CXX_FLAGS_INIT "-mmcu=${JA_AVR_MCU} -DF_CPU=${JA_AVR_F_CPU}UL")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-mmcu=${JA_AVR_MCU}")
set(CMAKE_EXECUTABLE_SUFFIX .elf)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
