// AVR assembly of the fixed-point multiply-accumulate kernels (numeric_policy.hpp: MacWide,
// MacWideB24, MacWide32x16, MsubWide32x16, MsubWide call these on the AVR; elsewhere the same
// functions are plain 64-bit arithmetic). Each adds (or subtracts) the exact signed 64-bit product
// to an accumulator held as {lo, hi} 32-bit words (Wide, fixed_point.hpp), by byte products
// a_i b_j summed column by column with their carries counted once per column, then the sign
// corrections: 64 add/adc per 32x32 MAC instead of 96, and no 8-byte temporary, so the kernel
// fits the registers inside a sum (NUMERICS.md). The results equal the x86 build's bit for bit:
// the filter bench hashes them over extreme and random operands at every carry and borrow edge
// on both (ctest firmware.avr_bench_filter: mac32x16_hash, mac_b24_hash, the filter states).
// Included by numeric_policy.hpp on AVR with MUL only.
#pragma once

#if !defined(__AVR__) || !defined(__AVR_HAVE_MUL__)
#error "fixed_mac_avr.hpp is the AVR (with MUL) build's: include numeric_policy.hpp"
#endif

#include <stdint.h>

#include "fixed_point.hpp"

namespace ja {
namespace core {
namespace detail {

/// Columns 0-2 of the column multiply-accumulate (byte products a_i b_j, i + j <= 2, carries
/// counted in [t]): the start of JA_AVR_MAC32_BODY and of MacWideB24Asm's 24-bit path alike.
#define JA_AVR_MAC_COLUMNS_0_2 \
  "clr %[t]\n\t"               \
  "mul %A[a], %A[b]\n\t"       \
  "add %A[lo], r0\n\t"         \
  "adc %B[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "add %C[lo], %[t]\n\t"       \
  "clr %[t]\n\t"               \
  "adc %[t], %[z]\n\t"         \
  "mul %A[a], %B[b]\n\t"       \
  "add %B[lo], r0\n\t"         \
  "adc %C[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "mul %B[a], %A[b]\n\t"       \
  "add %B[lo], r0\n\t"         \
  "adc %C[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "add %D[lo], %[t]\n\t"       \
  "clr %[t]\n\t"               \
  "adc %[t], %[z]\n\t"         \
  "mul %A[a], %C[b]\n\t"       \
  "add %C[lo], r0\n\t"         \
  "adc %D[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "mul %B[a], %B[b]\n\t"       \
  "add %C[lo], r0\n\t"         \
  "adc %D[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "mul %C[a], %A[b]\n\t"       \
  "add %C[lo], r0\n\t"         \
  "adc %D[lo], r1\n\t"         \
  "adc %[t], %[z]\n\t"         \
  "add %A[hi], %[t]\n\t"       \
  "clr %[t]\n\t"               \
  "adc %[t], %[z]\n\t"

/// MacWideAsm's kernel (below): the 32x32 column multiply-accumulate and its sign
/// corrections, labels 1 and 2, operands [lo], [hi], [t], [a], [b], [z]; also the full-width
/// path of MacWideB24Asm.
#define JA_AVR_MAC32_BODY                                                     \
  JA_AVR_MAC_COLUMNS_0_2                                                      \
  "mul %A[a], %D[b]\n\t"                                                      \
  "add %D[lo], r0\n\t"                                                        \
  "adc %A[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %B[a], %C[b]\n\t"                                                      \
  "add %D[lo], r0\n\t"                                                        \
  "adc %A[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %C[a], %B[b]\n\t"                                                      \
  "add %D[lo], r0\n\t"                                                        \
  "adc %A[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %D[a], %A[b]\n\t"                                                      \
  "add %D[lo], r0\n\t"                                                        \
  "adc %A[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "add %B[hi], %[t]\n\t"                                                      \
  "clr %[t]\n\t"                                                              \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %B[a], %D[b]\n\t"                                                      \
  "add %A[hi], r0\n\t"                                                        \
  "adc %B[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %C[a], %C[b]\n\t"                                                      \
  "add %A[hi], r0\n\t"                                                        \
  "adc %B[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %D[a], %B[b]\n\t"                                                      \
  "add %A[hi], r0\n\t"                                                        \
  "adc %B[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "add %C[hi], %[t]\n\t"                                                      \
  "clr %[t]\n\t"                                                              \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %C[a], %D[b]\n\t"                                                      \
  "add %B[hi], r0\n\t"                                                        \
  "adc %C[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "mul %D[a], %C[b]\n\t"                                                      \
  "add %B[hi], r0\n\t"                                                        \
  "adc %C[hi], r1\n\t"                                                        \
  "adc %[t], %[z]\n\t"                                                        \
  "add %D[hi], %[t]\n\t"                                                      \
  "mul %D[a], %D[b]\n\t"                                                      \
  "add %C[hi], r0\n\t"                                                        \
  "adc %D[hi], r1\n\t"                                                        \
  "clr __zero_reg__\n\t" /* signs: hi -= (a < 0 ? b : 0) + (b < 0 ? a : 0) */ \
  "sbrs %D[a], 7\n\t"                                                         \
  "rjmp 1f\n\t"                                                               \
  "sub %A[hi], %A[b]\n\t"                                                     \
  "sbc %B[hi], %B[b]\n\t"                                                     \
  "sbc %C[hi], %C[b]\n\t"                                                     \
  "sbc %D[hi], %D[b]\n"                                                       \
  "1:\n\t"                                                                    \
  "sbrs %D[b], 7\n\t"                                                         \
  "rjmp 2f\n\t"                                                               \
  "sub %A[hi], %A[a]\n\t"                                                     \
  "sbc %B[hi], %B[a]\n\t"                                                     \
  "sbc %C[hi], %C[a]\n\t"                                                     \
  "sbc %D[hi], %D[a]\n"                                                       \
  "2:\n"

/// acc += a * b (signed, modulo 2^64) with the product scanned straight into the accumulator,
/// column by column (byte products a_i b_j with i + j = c): each is added at bytes c, c + 1 and
/// its carry counted in one register t; at the end of the column t is added at byte c + 2 and
/// the carry of that add becomes the next column's t. So the kernel needs the accumulator, the
/// operands, t and a zero register (no 8-byte temporary; the product-then-add form runs out of
/// AVR registers inside a sum), and no carry ripples to the top per product (the former form
/// did: 96 add/adc per MAC, now 64). Unsigned bytes, then the sign correction
/// hi -= (a < 0 ? b : 0) + (b < 0 ? a : 0).
JA_FORCE_INLINE void MacWideAsm(Wide& acc, int32_t a, int32_t b) {
  uint32_t lo = acc.lo;
  uint32_t hi = static_cast<uint32_t>(acc.hi);
  const uint8_t zero = 0;
  uint8_t t;
  asm(JA_AVR_MAC32_BODY
      : [lo] "+r"(lo), [hi] "+r"(hi), [t] "=&r"(t)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  acc.lo = lo;
  acc.hi = static_cast<int32_t>(hi);
}

/// MacWideAsm with a test of b's width first: when b fits 24 bits (byte 3 is the sign of byte 2:
/// the readings, |a| < 128 m/s^2 in Q15.16) its 4 MULs with byte 3 are left out, 12 instead of
/// 16, and b's sign is corrected at byte 3 (b = ub - 2^24 [b < 0]); else the full product. The
/// same value either way. For the link rows (TermsKernel), whose readings nearly always fit:
/// ~20 cycles less a term, 5 more when b does not fit.
JA_FORCE_INLINE void MacWideB24Asm(Wide& acc, int32_t a, int32_t b) {
  uint32_t lo = acc.lo;
  uint32_t hi = static_cast<uint32_t>(acc.hi);
  const uint8_t zero = 0;
  uint8_t t;
  asm(
      // b within 24 bits (byte 3 = the sign of byte 2)? Else the 16-MUL product (label 5).
      "mov %[t], %C[b]\n\t"
      "lsl %[t]\n\t"
      "sbc %[t], %[t]\n\t"
      "cpse %[t], %D[b]\n\t"
      "rjmp 5f\n\t"
      // 12 MULs: ua times the 3 unsigned bytes ub of b, by columns as below; columns 0-2
      // (a0 b0; a0 b1, a1 b0; a0 b2, a1 b1, a2 b0) are those of the full product
      JA_AVR_MAC_COLUMNS_0_2
      // column 3: a1 b2, a2 b1, a3 b0 at bytes 3, 4
      "mul %B[a], %C[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %B[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %A[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %B[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 4: a2 b2, a3 b1 at bytes 4, 5
      "mul %C[a], %C[b]\n\t"
      "add %A[hi], r0\n\t"
      "adc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %B[b]\n\t"
      "add %A[hi], r0\n\t"
      "adc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %C[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 5: a3 b2 at bytes 5, 6
      "mul %D[a], %C[b]\n\t"
      "add %B[hi], r0\n\t"
      "adc %C[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %D[hi], %[t]\n\t"
      "clr __zero_reg__\n\t"
      // signs (a = ua - 2^32 [a < 0], b = ub - 2^24 [b < 0]):
      // a b = ua ub - 2^32 ub [a < 0] - 2^24 ua [b < 0] + 2^56 [a < 0][b < 0]
      "sbrs %D[a], 7\n\t"
      "rjmp 3f\n\t"
      "sub %A[hi], %A[b]\n\t"
      "sbc %B[hi], %B[b]\n\t"
      "sbc %C[hi], %C[b]\n\t"
      "sbc %D[hi], %[z]\n\t"
      "sbrc %D[b], 7\n\t"
      "inc %D[hi]\n\t"
      "3:\n\t"
      "sbrs %D[b], 7\n\t"
      "rjmp 4f\n\t"
      "sub %D[lo], %A[a]\n\t"
      "sbc %A[hi], %B[a]\n\t"
      "sbc %B[hi], %C[a]\n\t"
      "sbc %C[hi], %D[a]\n\t"
      "sbc %D[hi], %[z]\n\t"
      "4:\n\t"
      "rjmp 6f\n"
      "5:\n\t" JA_AVR_MAC32_BODY "6:"
      : [lo] "+r"(lo), [hi] "+r"(hi), [t] "=&r"(t)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  acc.lo = lo;
  acc.hi = static_cast<int32_t>(hi);
}

/// acc += a * b (signed, modulo 2^64) for a 16-bit signed b: 8 MULs instead of 16. The unsigned
/// byte products ua_i ub_j by columns as in MacWideAsm (columns 0..4, carries counted in t and
/// added once per column; the last column's carry rippled to byte 7), then the signs, with
/// a = ua - 2^32 [a < 0] and b = ub - 2^16 [b < 0]:
///   a b = ua ub - 2^16 ua [b < 0] - 2^32 b [a < 0]      (b sign-extended in the last term),
/// i.e. ua subtracted at byte 2 (6 bytes, borrow to the top) when b < 0 and b subtracted from
/// the high word when a < 0.
JA_FORCE_INLINE void MacWide32x16Asm(Wide& acc, int32_t a, int16_t b) {
  uint32_t lo = acc.lo;
  uint32_t hi = static_cast<uint32_t>(acc.hi);
  const uint8_t zero = 0;
  uint8_t t;
  asm("clr %[t]\n\t"
      // column 0: a0 b0 at bytes 0, 1
      "mul %A[a], %A[b]\n\t"
      "add %A[lo], r0\n\t"
      "adc %B[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %C[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 1: a0 b1, a1 b0 at bytes 1, 2
      "mul %A[a], %B[b]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %A[b]\n\t"
      "add %B[lo], r0\n\t"
      "adc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %D[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 2: a1 b1, a2 b0 at bytes 2, 3
      "mul %B[a], %B[b]\n\t"
      "add %C[lo], r0\n\t"
      "adc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %A[b]\n\t"
      "add %C[lo], r0\n\t"
      "adc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %A[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 3: a2 b1, a3 b0 at bytes 3, 4
      "mul %C[a], %B[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %A[b]\n\t"
      "add %D[lo], r0\n\t"
      "adc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %B[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 4: a3 b1 at bytes 4, 5; the carries to bytes 6, 7
      "mul %D[a], %B[b]\n\t"
      "add %A[hi], r0\n\t"
      "adc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "add %C[hi], %[t]\n\t"
      "adc %D[hi], %[z]\n\t"
      "clr __zero_reg__\n\t"
      // b < 0: acc -= ua 2^16
      "sbrs %B[b], 7\n\t"
      "rjmp 1f\n\t"
      "sub %C[lo], %A[a]\n\t"
      "sbc %D[lo], %B[a]\n\t"
      "sbc %A[hi], %C[a]\n\t"
      "sbc %B[hi], %D[a]\n\t"
      "sbc %C[hi], %[z]\n\t"
      "sbc %D[hi], %[z]\n"
      "1:\n\t"
      // a < 0: acc -= b 2^32 (b sign-extended: t = 0 or 0xFF)
      "sbrs %D[a], 7\n\t"
      "rjmp 2f\n\t"
      "mov %[t], %B[b]\n\t"
      "lsl %[t]\n\t"
      "sbc %[t], %[t]\n\t"
      "sub %A[hi], %A[b]\n\t"
      "sbc %B[hi], %B[b]\n\t"
      "sbc %C[hi], %[t]\n\t"
      "sbc %D[hi], %[t]\n"
      "2:"
      : [lo] "+r"(lo), [hi] "+r"(hi), [t] "=&r"(t)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  acc.lo = lo;
  acc.hi = static_cast<int32_t>(hi);
}

/// acc -= a * b (signed, modulo 2^64) for a 16-bit signed b: MacWide32x16Asm with sub/sbc (t
/// counts the borrows) and the sign terms added back: acc - a b = acc - ua ub + 2^16 ua [b < 0]
/// + 2^32 b [a < 0].
JA_FORCE_INLINE void MsubWide32x16Asm(Wide& acc, int32_t a, int16_t b) {
  uint32_t lo = acc.lo;
  uint32_t hi = static_cast<uint32_t>(acc.hi);
  const uint8_t zero = 0;
  uint8_t t;
  asm("clr %[t]\n\t"
      // column 0: a0 b0 at bytes 0, 1
      "mul %A[a], %A[b]\n\t"
      "sub %A[lo], r0\n\t"
      "sbc %B[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %C[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 1: a0 b1, a1 b0 at bytes 1, 2
      "mul %A[a], %B[b]\n\t"
      "sub %B[lo], r0\n\t"
      "sbc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %A[b]\n\t"
      "sub %B[lo], r0\n\t"
      "sbc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %D[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 2: a1 b1, a2 b0 at bytes 2, 3
      "mul %B[a], %B[b]\n\t"
      "sub %C[lo], r0\n\t"
      "sbc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %A[b]\n\t"
      "sub %C[lo], r0\n\t"
      "sbc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %A[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 3: a2 b1, a3 b0 at bytes 3, 4
      "mul %C[a], %B[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %A[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %B[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      // column 4: a3 b1 at bytes 4, 5; the borrows to bytes 6, 7
      "mul %D[a], %B[b]\n\t"
      "sub %A[hi], r0\n\t"
      "sbc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %C[hi], %[t]\n\t"
      "sbc %D[hi], %[z]\n\t"
      "clr __zero_reg__\n\t"
      // b < 0: acc += ua 2^16
      "sbrs %B[b], 7\n\t"
      "rjmp 1f\n\t"
      "add %C[lo], %A[a]\n\t"
      "adc %D[lo], %B[a]\n\t"
      "adc %A[hi], %C[a]\n\t"
      "adc %B[hi], %D[a]\n\t"
      "adc %C[hi], %[z]\n\t"
      "adc %D[hi], %[z]\n"
      "1:\n\t"
      // a < 0: acc += b 2^32 (b sign-extended: t = 0 or 0xFF)
      "sbrs %D[a], 7\n\t"
      "rjmp 2f\n\t"
      "mov %[t], %B[b]\n\t"
      "lsl %[t]\n\t"
      "sbc %[t], %[t]\n\t"
      "add %A[hi], %A[b]\n\t"
      "adc %B[hi], %B[b]\n\t"
      "adc %C[hi], %[t]\n\t"
      "adc %D[hi], %[t]\n"
      "2:"
      : [lo] "+r"(lo), [hi] "+r"(hi), [t] "=&r"(t)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  acc.lo = lo;
  acc.hi = static_cast<int32_t>(hi);
}

/// acc -= a * b (signed, modulo 2^64); as MacWideAsm with sub/sbc (t counts the borrows).
JA_FORCE_INLINE void MsubWideAsm(Wide& acc, int32_t a, int32_t b) {
  uint32_t lo = acc.lo;
  uint32_t hi = static_cast<uint32_t>(acc.hi);
  const uint8_t zero = 0;
  uint8_t t;
  asm("clr %[t]\n\t"
      "mul %A[a], %A[b]\n\t"
      "sub %A[lo], r0\n\t"
      "sbc %B[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %C[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %A[a], %B[b]\n\t"
      "sub %B[lo], r0\n\t"
      "sbc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %A[b]\n\t"
      "sub %B[lo], r0\n\t"
      "sbc %C[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %D[lo], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %A[a], %C[b]\n\t"
      "sub %C[lo], r0\n\t"
      "sbc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %B[b]\n\t"
      "sub %C[lo], r0\n\t"
      "sbc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %A[b]\n\t"
      "sub %C[lo], r0\n\t"
      "sbc %D[lo], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %A[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %A[a], %D[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %C[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %B[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %A[b]\n\t"
      "sub %D[lo], r0\n\t"
      "sbc %A[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %B[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %B[a], %D[b]\n\t"
      "sub %A[hi], r0\n\t"
      "sbc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %C[b]\n\t"
      "sub %A[hi], r0\n\t"
      "sbc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %B[b]\n\t"
      "sub %A[hi], r0\n\t"
      "sbc %B[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %C[hi], %[t]\n\t"
      "clr %[t]\n\t"
      "adc %[t], %[z]\n\t"
      "mul %C[a], %D[b]\n\t"
      "sub %B[hi], r0\n\t"
      "sbc %C[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "mul %D[a], %C[b]\n\t"
      "sub %B[hi], r0\n\t"
      "sbc %C[hi], r1\n\t"
      "adc %[t], %[z]\n\t"
      "sub %D[hi], %[t]\n\t"
      "mul %D[a], %D[b]\n\t"
      "sub %C[hi], r0\n\t"
      "sbc %D[hi], r1\n\t"
      "clr __zero_reg__\n\t"
      // signs: hi += (a < 0 ? b : 0) + (b < 0 ? a : 0), skips in assembly
      "sbrs %D[a], 7\n\t"
      "rjmp 1f\n\t"
      "add %A[hi], %A[b]\n\t"
      "adc %B[hi], %B[b]\n\t"
      "adc %C[hi], %C[b]\n\t"
      "adc %D[hi], %D[b]\n"
      "1:\n\t"
      "sbrs %D[b], 7\n\t"
      "rjmp 2f\n\t"
      "add %A[hi], %A[a]\n\t"
      "adc %B[hi], %B[a]\n\t"
      "adc %C[hi], %C[a]\n\t"
      "adc %D[hi], %D[a]\n"
      "2:"
      : [lo] "+r"(lo), [hi] "+r"(hi), [t] "=&r"(t)
      : [a] "r"(a), [b] "r"(b), [z] "r"(zero)
      : "r0");
  acc.lo = lo;
  acc.hi = static_cast<int32_t>(hi);
}

}  // namespace detail
}  // namespace core
}  // namespace ja
