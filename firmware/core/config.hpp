// The one documented configuration header of the firmware core: Eigen's options, and the
// compiler quirks the core depends on (read-only tables in flash). Every file in firmware/
// includes Eigen through this header, never <Eigen/...> directly, so all translation units see
// the same options and therefore the same types and memory layouts.
//
// ---- Eigen ----
// Options (identical on every platform):
//   EIGEN_NO_DEBUG            no eigen_assert: no <cassert> paths, no runtime checks on the MCU.
//   EIGEN_DONT_VECTORIZE      no SIMD packets: AVR has none, and x86 must compute the same way.
//   EIGEN_MAX_ALIGN_BYTES 0   and EIGEN_MAX_STATIC_ALIGN_BYTES 0: plain C layout, no padding
//                             (the AVR has 1-byte alignment; x86 structs then match its sizes).
//   EIGEN_NO_MALLOC           fixed-size matrices only; a heap allocation would assert (x86 debug
//                             builds of Eigen) and on the AVR operator new is not even defined.
//   EIGEN_NO_IO               no <iostream>/<sstream> machinery (operator<< for matrices).
//   EIGEN_MPL2_ONLY           refuse the few LGPL parts.
//   EIGEN_HAS_CXX11_ATOMIC 0  no <atomic> (Eigen's unused multithreading hooks).
// AVR only (avr-gcc 5.4, int = 16 bits, no C++ standard library):
//   - the standard headers come from firmware/platform/avr/include (freestanding subset);
//   - EIGEN_HAS_CXX11_MATH 0: avr-libc has no asinh/acosh/atanh/expm1/log1p;
//   - EIGEN_NO_STATIC_ASSERT: Eigen's internal cost check computes HugeCost*HugeCost = 1e8 in
//     `int`, which overflows a 16-bit int and fails spuriously; the x86 build keeps every static
//     assertion, so the same source is still checked;
//   - bfloat16: Eigen declares raw_uint16_to_bfloat16(unsigned short) but defines it for
//     numext::uint16_t, which is `unsigned int` on AVR, so calls with an int literal are
//     ambiguous; an int overload (and the forward declaration of the uint16_t one) settles it;
//   - avr-gcc wraps every -isystem header in an implicit extern "C", so Eigen is on the plain -I
//     path there and its own 16-bit-int warnings are silenced here, only for Eigen's headers.
#pragma once

#define EIGEN_NO_DEBUG 1
#define EIGEN_DONT_VECTORIZE 1
#define EIGEN_MAX_ALIGN_BYTES 0
#define EIGEN_MAX_STATIC_ALIGN_BYTES 0
#define EIGEN_NO_MALLOC 1
#define EIGEN_NO_IO 1
#define EIGEN_MPL2_ONLY 1
#define EIGEN_HAS_CXX11_ATOMIC 0

#if defined(__AVR__)
#define EIGEN_HAS_CXX11_MATH 0
#define EIGEN_NO_STATIC_ASSERT 1
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"
#pragma GCC diagnostic ignored "-Wshift-count-overflow"
#pragma GCC diagnostic ignored "-Woverflow"
#pragma GCC diagnostic ignored "-Wunused-variable"
#pragma GCC diagnostic ignored "-Wunused-local-typedefs"
#pragma GCC diagnostic ignored "-Wtype-limits"
namespace Eigen {
namespace bfloat16_impl {
struct __bfloat16_raw;
constexpr __bfloat16_raw raw_uint16_to_bfloat16(int value);
constexpr __bfloat16_raw raw_uint16_to_bfloat16(unsigned int value);
}  // namespace bfloat16_impl
}  // namespace Eigen
#endif

#include <Eigen/Core>
#include <Eigen/LU>  // fixed-size inverse(), for float reference code only

#if defined(__AVR__)
namespace Eigen {
namespace bfloat16_impl {
constexpr __bfloat16_raw raw_uint16_to_bfloat16(int value) {
  return raw_uint16_to_bfloat16(static_cast<numext::uint16_t>(value));
}
}  // namespace bfloat16_impl
}  // namespace Eigen
#pragma GCC diagnostic pop
#endif

// ---- Read-only tables ----
// JA_ROM places a constant table in program memory on AVR (8 KB of SRAM is too little to copy
// tables into it), and ReadRom() reads one entry back. avr-g++ 5.4 has no __flash in C++, so the
// read is the LPM instruction itself; tables stay below 64 KB (.progmem comes first in flash).
// Elsewhere JA_ROM is empty and ReadRom() a plain load.
#include <stdint.h>
#if defined(__AVR__)
#define JA_ROM __attribute__((__progmem__))
namespace ja {
namespace core {
inline int32_t ReadRom(const int32_t* p) {
  uint32_t v;
  asm("lpm %A0, Z+\n\t"
      "lpm %B0, Z+\n\t"
      "lpm %C0, Z+\n\t"
      "lpm %D0, Z"
      : "=r"(v), "+z"(p));
  return static_cast<int32_t>(v);
}
}  // namespace core
}  // namespace ja
#else
#define JA_ROM
namespace ja {
namespace core {
inline int32_t ReadRom(const int32_t* p) { return *p; }
}  // namespace core
}  // namespace ja
#endif
