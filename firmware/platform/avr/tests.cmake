# ctests of the Mega 2560 image and the Arduino sketch, included from firmware/CMakeLists.txt
# (the image itself is built by the avr_images ExternalProject into <build>/avr).
# The driver, test_mega2560_image.py, is in firmware/tests/boards with the other boards'.
set(JA_MEGA_ELF ${CMAKE_BINARY_DIR}/avr/jointangle_mega2560.elf)
set(JA_MEGA_TEST ${PROJECT_SOURCE_DIR}/firmware/tests/boards/test_mega2560_image.py)

# The image in the AVR virtual board: hello, a stream of sample_estimate frames with every
# sensor fresh, SRAM budget; prints flash/RAM/stack and the loop accounting.
if(TARGET ja_avr_board)
  add_test(NAME firmware.avr_image_stream
           COMMAND Python3::Interpreter ${JA_MEGA_TEST}
                   $<TARGET_FILE:ja_avr_board> ${JA_MEGA_ELF} 2)
  set_tests_properties(firmware.avr_image_stream PROPERTIES TIMEOUT 600
                       ENVIRONMENT JA_AVR_TEST_RATE=100)  # README.md: the loop budget
  # A sensor NACKing for 0.3 s (real-time board): flagged, the rest streams on, re-probed.
  add_test(NAME firmware.avr_image_nack
           COMMAND Python3::Interpreter ${JA_MEGA_TEST}
                   $<TARGET_FILE:ja_avr_board> ${JA_MEGA_ELF} 3 nack)
  set_tests_properties(firmware.avr_image_nack PROPERTIES TIMEOUT 600
                       ENVIRONMENT JA_AVR_TEST_RATE=100)
  # Asked for more than the loop holds (500 Hz): every frame one or two periods after the last.
  add_test(NAME firmware.avr_image_overload
           COMMAND Python3::Interpreter ${JA_MEGA_TEST}
                   $<TARGET_FILE:ja_avr_board> ${JA_MEGA_ELF} 2 overload)
  set_tests_properties(firmware.avr_image_overload PROPERTIES TIMEOUT 600
                       ENVIRONMENT JA_AVR_TEST_RATE=500)
else()
  add_test(NAME firmware.avr_image_stream
           COMMAND sh -c "echo 'ja_avr_board not built (simavr/libelf missing): run scripts/setup.sh'; false")
endif()

# The sketch built with Debian's arduino-mk the way a user does (make -C <sketch> OBJDIR=...),
# into the build tree; checks the HEX and that src/ covers exactly the image's sources.
add_test(NAME firmware.avr_sketch_arduino_mk
         COMMAND ${CMAKE_COMMAND} -DSKETCH=${PROJECT_SOURCE_DIR}/firmware/sketches/JointAngle
                 -DFIRMWARE=${PROJECT_SOURCE_DIR}/firmware
                 -DOBJDIR=${CMAKE_CURRENT_BINARY_DIR}/sketch-JointAngle
                 -P ${PROJECT_SOURCE_DIR}/firmware/sketches/check_sketch.cmake)
set_tests_properties(firmware.avr_sketch_arduino_mk PROPERTIES TIMEOUT 900
                     FIXTURES_SETUP avr_sketch_elf)
# ... and the sketch's ELF (Arduino core underneath) behaves like the CMake image.
if(TARGET ja_avr_board)
  add_test(NAME firmware.avr_sketch_stream
           COMMAND Python3::Interpreter ${JA_MEGA_TEST}
                   $<TARGET_FILE:ja_avr_board>
                   ${CMAKE_CURRENT_BINARY_DIR}/sketch-JointAngle/JointAngle.elf 1)
  set_tests_properties(firmware.avr_sketch_stream PROPERTIES TIMEOUT 600
                       FIXTURES_REQUIRED avr_sketch_elf ENVIRONMENT JA_AVR_TEST_RATE=100)
endif()
