# ctests of the Raspberry Pi Pico (RP2040) image, included from firmware/CMakeLists.txt (the
# image itself is built by the pico_images ExternalProject into <build>/pico). The driver,
# test_pico_image.py, is in firmware/tests/boards with the other boards'.
set(JA_PICO_ELF ${CMAKE_BINARY_DIR}/pico/jointangle_pico.elf)
set(JA_PICO_BIN ${CMAKE_BINARY_DIR}/pico/jointangle_pico.bin)
set(JA_PICO_TEST ${PROJECT_SOURCE_DIR}/firmware/tests/boards/test_pico_image.py)

# boot2's CRC as the bootrom checks it; the vector table boot2 enters; flash and RAM use.
foreach(check boot2_crc vectors size)
  string(REPLACE "_crc" "" mode ${check})
  if(JA_ARM_GXX)
    add_test(NAME firmware.pico_image_${check}
             COMMAND Python3::Interpreter ${JA_PICO_TEST} ${mode} ${JA_PICO_ELF} ${JA_PICO_BIN})
  else()
    add_test(NAME firmware.pico_image_${check}
             COMMAND sh -c "echo 'arm-none-eabi-g++ not found, so no Pico image to test: run scripts/setup.sh (it installs gcc-arm-none-eabi, libnewlib-arm-none-eabi, libstdc++-arm-none-eabi-newlib)'; false")
  endif()
endforeach()
# The UF2 (the host's converter, run by the build) holds exactly the image's bytes.
set(JA_PICO_UF2 ${CMAKE_BINARY_DIR}/pico/jointangle_pico.uf2)
if(JA_ARM_GXX)
  add_test(NAME firmware.pico_image_uf2
           COMMAND Python3::Interpreter ${JA_PICO_TEST} uf2 ${JA_PICO_ELF} ${JA_PICO_BIN}
                   ${JA_PICO_UF2})
else()
  add_test(NAME firmware.pico_image_uf2
           COMMAND sh -c "echo 'arm-none-eabi-g++ not found, so no Pico image to test: run scripts/setup.sh'; false")
endif()
# The build's boot2 tool: pads, appends a CRC the test's own implementation agrees with, refuses
# code longer than 252 bytes (needs no cross compiler).
add_test(NAME firmware.pico_boot2_tool
         COMMAND Python3::Interpreter ${JA_PICO_TEST} tool
                 ${PROJECT_SOURCE_DIR}/firmware/tools/pico_boot2.py)
# The joint filter on the Pico (bench_filter.elf in the emulator's cycle harness): every step of
# the AVR bench's input (10 s of every scenario, general geometry, 3 and 4 sensors a link), fixed
# point and float, each step timed; every fixed-point check line identical to x86's. Ceilings
# ~10 % above today's worst steps (rp2040js cycle estimates), regression guards.
set(JA_PICO_FILTER_LIMITS "filter_fixed=22600" "filter_float=58200" "filter_fixed_n3=24500"
    "filter_fixed_n4=26600" "filter_fixed_release=27400")
find_program(JA_NODE node)
if(JA_ARM_GXX AND JA_NODE AND TARGET bench_filter_native)
  add_test(NAME firmware.pico_bench_filter
           COMMAND ${CMAKE_COMMAND}
                   -DHARNESS=${PROJECT_SOURCE_DIR}/firmware/sim/pico_board/pico_cycles.mjs
                   -DELF=${CMAKE_BINARY_DIR}/pico/bench_filter.elf
                   -DNATIVE=$<TARGET_FILE:bench_filter_native>
                   -DINPUT=${CMAKE_BINARY_DIR}/avr/bench_filter_input.bin
                   -DOUT=${CMAKE_BINARY_DIR}/pico/bench_filter.json
                   "-DLIMITS=${JA_PICO_FILTER_LIMITS}" -DTIMEOUT=170
                   -P ${PROJECT_SOURCE_DIR}/firmware/tests/run_avr_bench.cmake)
  set_tests_properties(firmware.pico_bench_filter PROPERTIES TIMEOUT 180
                       FIXTURES_REQUIRED avr_filter_input)
else()
  add_test(NAME firmware.pico_bench_filter
           COMMAND sh -c "echo 'the Pico filter bench needs arm-none-eabi-g++ and node: run scripts/setup.sh'; false")
endif()
# The Pico virtual board's own models (node:test): the PL011's timing and interrupts, the bootrom's
# flash functions and boot2 check (firmware/sim/pico_board/test).
if(JA_NODE)
  add_test(NAME firmware.sim.pico_board_models
           COMMAND ${JA_NODE} --test ${PROJECT_SOURCE_DIR}/firmware/sim/pico_board/test/)
else()
  add_test(NAME firmware.sim.pico_board_models
           COMMAND sh -c "echo 'node not found: run scripts/setup.sh'; false")
endif()
