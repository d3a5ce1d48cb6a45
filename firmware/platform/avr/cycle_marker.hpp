// Cycle markers for firmware/sim/avr_cycles: the firmware brackets code with region markers that
// the simavr harness timestamps cycle-exactly, and prints through a one-register console.
// GPIOR0 = region id (open) / 0 (close); GPIOR2 = console byte. Costs one `out` per marker.
#pragma once
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>

namespace ja {
namespace avr {

/// Opens cycle region `id` (1..255). The memory clobber keeps the compiler from moving memory
/// accesses across the marker.
inline void BeginRegion(uint8_t id) {
  asm volatile("" ::: "memory");
  GPIOR0 = id;
  asm volatile("" ::: "memory");
}

/// Closes the open region.
inline void EndRegion() {
  asm volatile("" ::: "memory");
  GPIOR0 = 0;
  asm volatile("" ::: "memory");
}

/// Writes a string to the harness console.
inline void ConsolePrint(const char* s) {
  while (*s) GPIOR2 = static_cast<uint8_t>(*s++);
}

/// Writes a signed decimal integer to the harness console.
inline void ConsolePrintInt(int32_t v) {
  char buf[12];
  uint8_t n = 0;
  uint32_t u = v < 0 ? 0u - static_cast<uint32_t>(v) : static_cast<uint32_t>(v);
  do {
    buf[n++] = static_cast<char>('0' + u % 10u);
    u /= 10u;
  } while (u);
  if (v < 0) GPIOR2 = '-';
  while (n) GPIOR2 = static_cast<uint8_t>(buf[--n]);
}

/// Ends the simulation: sleeping with interrupts disabled makes simavr stop (cpu_Done).
[[noreturn]] inline void StopSimulation() {
  sleep_enable();
  cli();
  for (;;) sleep_cpu();
}

}  // namespace avr
}  // namespace ja
