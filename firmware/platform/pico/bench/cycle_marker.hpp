// Cycle markers for the Pico cycle harness (firmware/sim/pico_board/pico_cycles.mjs): the bench
// images bracket code with region markers that the emulator timestamps with its core cycle count,
// print through a console and read their input, each a breakpoint the harness answers
// (bkpt #0x20..#0x24; without a debugger a real chip would fault there: bench images only).
// The memory clobbers keep the compiler from moving memory accesses across a marker.
#pragma once
#include <stdint.h>

namespace ja {
namespace pico {

/// Opens cycle region `id` (1..255).
inline void BeginRegion(uint8_t id) {
  register uint32_t r0 asm("r0") = id;
  asm volatile("bkpt #0x20" : : "r"(r0) : "memory");
}

/// Closes the open region.
inline void EndRegion() { asm volatile("bkpt #0x21" : : : "memory"); }

/// Writes a NUL-terminated string to the harness console.
inline void ConsolePrint(const char* s) {
  register const char* r0 asm("r0") = s;
  asm volatile("bkpt #0x22" : : "r"(r0) : "memory");
}

/// Writes a signed decimal integer to the harness console.
inline void ConsolePrintInt(int32_t v) {
  char buf[12];
  char* p = buf + sizeof buf - 1;
  *p = '\0';
  uint32_t u = v < 0 ? 0u - static_cast<uint32_t>(v) : static_cast<uint32_t>(v);
  do {
    *--p = static_cast<char>('0' + u % 10u);
    u /= 10u;
  } while (u);
  if (v < 0) *--p = '-';
  ConsolePrint(p);
}

/// The next byte of the harness's --input (0 past its end, counted as an overrun).
inline uint8_t ReadInputByte() {
  register uint32_t r0 asm("r0");
  asm volatile("bkpt #0x23" : "=r"(r0) : : "memory");
  return static_cast<uint8_t>(r0);
}

/// Ends the run.
[[noreturn]] inline void StopSimulation() {
  for (;;) asm volatile("bkpt #0x24");
}

}  // namespace pico
}  // namespace ja
