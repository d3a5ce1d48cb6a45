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
