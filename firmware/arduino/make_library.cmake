# The firmware as an Arduino library (README.md beside this file), from the sources the CMake
# image is built from:
#
#   cmake -DFIRMWARE=<repo>/firmware -DEIGEN=<eigen3 include dir> -DOUT=<dir> -DVERSION=x.y.z
#         -P make_library.cmake
#
# writes <OUT>/JointAngle/ (library.properties, src/, examples/JointAngle/JointAngle.ino) and
# <OUT>/JointAngle-<VERSION>.zip, which the IDE's "Add .ZIP Library" and
# `arduino-cli lib install --zip-path` accept. src/ keeps the firmware's layout (its includes
# are "app/app.hpp", "core/...", relative to the firmware folder, which is the library's src/),
# adds the freestanding C++ headers Eigen needs on avr-gcc at its root (<cmath>, <type_traits>,
# ...: an Arduino library has only src/ on the include path) and Eigen itself.
cmake_minimum_required(VERSION 3.25)
foreach(v FIRMWARE EIGEN OUT VERSION)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "make_library.cmake: -D${v}=... is required")
  endif()
endforeach()
set(here ${CMAKE_CURRENT_LIST_DIR})
set(lib ${OUT}/JointAngle)
file(REMOVE_RECURSE ${lib})
file(MAKE_DIRECTORY ${lib}/src ${lib}/examples/JointAngle)

# The image's sources and headers (firmware/platform/avr/CMakeLists.txt, as the sketch's
# check_sketch.cmake lists them); main.cpp is the CMake image's entry point, the sketch has
# setup().
file(GLOB_RECURSE files RELATIVE ${FIRMWARE}
     ${FIRMWARE}/app/*.cpp ${FIRMWARE}/app/*.hpp ${FIRMWARE}/drivers/*.cpp
     ${FIRMWARE}/drivers/*.hpp ${FIRMWARE}/protocol/*.cpp ${FIRMWARE}/protocol/*.hpp
     ${FIRMWARE}/core/*.hpp ${FIRMWARE}/platform/avr/board/*.cpp
     ${FIRMWARE}/platform/avr/board/*.hpp)
list(REMOVE_ITEM files platform/avr/board/main.cpp)
foreach(f IN LISTS files)
  get_filename_component(dir ${f} DIRECTORY)
  file(COPY ${FIRMWARE}/${f} DESTINATION ${lib}/src/${dir})
endforeach()
file(GLOB std_headers ${FIRMWARE}/platform/avr/include/*)
file(COPY ${std_headers} DESTINATION ${lib}/src)
file(COPY ${EIGEN}/Eigen DESTINATION ${lib}/src)
# Eigen's licence travels with it: its COPYING.MPL2, or Debian's copyright file for it.
foreach(licence ${EIGEN}/COPYING.MPL2 ${EIGEN}/../../share/doc/libeigen3-dev/copyright)
  if(EXISTS ${licence})
    file(COPY ${licence} DESTINATION ${lib}/src/Eigen)
    break()
  endif()
endforeach()
file(COPY ${here}/JointAngle.h DESTINATION ${lib}/src)

configure_file(${here}/library.properties.in ${lib}/library.properties @ONLY)
# The example is the repository's sketch, including the library's header instead of the
# firmware's through an include path.
file(READ ${FIRMWARE}/sketches/JointAngle/JointAngle.ino ino)
string(REPLACE "#include \"platform/avr/board/board.hpp\"" "#include <JointAngle.h>" ino "${ino}")
if(NOT ino MATCHES "#include <JointAngle.h>")
  message(FATAL_ERROR "make_library.cmake: the sketch no longer includes board.hpp: update me")
endif()
file(WRITE ${lib}/examples/JointAngle/JointAngle.ino "${ino}")

set(zip ${OUT}/JointAngle-${VERSION}.zip)
file(REMOVE ${zip})
execute_process(COMMAND ${CMAKE_COMMAND} -E tar cf ${zip} --format=zip JointAngle
                WORKING_DIRECTORY ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "make_library.cmake: zipping ${lib} failed")
endif()
list(LENGTH files n)
message(STATUS "Arduino library: ${zip} (${n} firmware files, Eigen from ${EIGEN})")
