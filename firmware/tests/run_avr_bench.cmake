# Runs an AVR bench image in simavr through firmware/sim/avr_cycles and checks it:
#  - the run finished (cpu_Done) with balanced region markers;
#  - every "check NAME VALUE" console line equals the x86 build's (bit-exact fixed point);
#  - every region in LIMITS ("name=max_cycles;...") stays at or under its ceiling.
# The harness JSON is kept in OUT (bench and NUMERICS.md read it).
# cmake -DHARNESS=... -DELF=... -DNATIVE=... -DOUT=... -DLIMITS=... -P run_avr_bench.cmake
foreach(var HARNESS ELF NATIVE OUT)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "${var} not set")
  endif()
endforeach()

execute_process(COMMAND ${HARNESS} ${ELF} OUTPUT_VARIABLE json ERROR_VARIABLE log
                RESULT_VARIABLE rc TIMEOUT 170)
file(WRITE ${OUT} "${json}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "avr_cycles failed (${rc}):\n${log}\n${json}")
endif()
string(JSON state GET "${json}" state)
if(NOT state STREQUAL "done")
  message(FATAL_ERROR "simulation ended in state ${state}")
endif()

execute_process(COMMAND ${NATIVE} OUTPUT_VARIABLE native RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "native bench failed (${rc})")
endif()
string(REGEX MATCHALL "check [a-z0-9_]+ -?[0-9]+" native_checks "${native}")

string(JSON n_console LENGTH "${json}" console)
set(avr_checks "")
math(EXPR last "${n_console} - 1")
foreach(i RANGE ${last})
  string(JSON line GET "${json}" console ${i})
  message(STATUS "avr: ${line}")
  if(line MATCHES "^check ")
    list(APPEND avr_checks "${line}")
  endif()
endforeach()
list(LENGTH avr_checks n_checks)
if(n_checks EQUAL 0)
  message(FATAL_ERROR "the AVR image printed no check lines")
endif()
if(NOT avr_checks STREQUAL native_checks)
  message(FATAL_ERROR "fixed-point results differ between AVR and x86:\n avr:    ${avr_checks}\n"
                      " native: ${native_checks}")
endif()
message(STATUS "${n_checks} fixed-point checks identical on AVR and x86")

foreach(limit IN LISTS LIMITS)
  string(REPLACE "=" ";" pair "${limit}")
  list(GET pair 0 name)
  list(GET pair 1 ceiling)
  string(JSON cycles ERROR_VARIABLE missing GET "${json}" regions ${name} max)
  if(missing)
    message(FATAL_ERROR "region ${name} was not measured")
  endif()
  if(cycles GREATER ceiling)
    message(FATAL_ERROR "${name}: ${cycles} cycles > ceiling ${ceiling}")
  endif()
  message(STATUS "${name}: ${cycles} cycles (ceiling ${ceiling})")
endforeach()
