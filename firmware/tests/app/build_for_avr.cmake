# Compiles and links the application for the ATmega2560 (avr-gcc 5.4, C++14) over stub hardware
# and prints avr-size. Run: cmake -DGXX=... -DSIZE=... -DFIRMWARE=... -DSOURCES=a;b -DOUT=... -P
execute_process(
  COMMAND ${GXX} -std=gnu++14 -mmcu=atmega2560 -DF_CPU=16000000UL -Os -Wall -Wextra -Werror
          -fno-exceptions -fno-rtti -fno-threadsafe-statics -ffunction-sections -fdata-sections
          -Wl,--gc-sections -I${FIRMWARE}/platform/avr/include -I${EIGEN} -I${FIRMWARE}
          ${SOURCES} -o ${OUT}
  RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "avr-g++ failed (${rc})")
endif()
execute_process(COMMAND ${SIZE} --format=avr --mcu=atmega2560 ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "avr-size failed (${rc})")
endif()
