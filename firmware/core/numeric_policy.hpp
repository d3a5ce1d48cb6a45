// Numeric policies of the joint filter (joint_filter.hpp): one scalar type per quantity, and the
// mixed-type arithmetic the filter is written in, so one source instantiates with float
// everywhere (FloatPolicy) and with per-quantity Q formats (FixedPolicy, the firmware's).
//
//   Mul<R>(a, b)      a * b as type R           (Fixed: one 64-bit product, one rounding)
//   Cast<R>(a)        a as type R               (Fixed: re-scaled, rounded, saturated)
//   Recip<R>(a)       1 / a as type R           (Fixed: one division of 2^(Fr+Fa) by a)
//   Sqrt<R>(a)        sqrt(a) as type R, 0 for a <= 0 (Fixed: integer square root)
//   Sum<R, A, B>      sum of products a_i * b_i as R, rounded once (wide accumulator)
//   ToFloat(a), FromFloat<R>(v)                 configuration and reporting only
//
// Every fixed-point operation rounds half up (floor(x + 1/2)) and saturates, counting the
// saturation in SaturationCount() — the same on AVR and x86, bit for bit. The Q format of each
// quantity is chosen from its measured range (FILTER.md, "Q formats").
#pragma once

#include <stdint.h>

#include "fixed_point.hpp"
#include "fixed_round_avr.hpp"
#include "scalar_math.hpp"

namespace ja {
namespace core {

/// A real number in Q(15-F).F as int16: raw = round(value * 2^F). The 16-bit operand of the
/// 32x16 products (MacWide32x16, MsubWide32x16: 8 MULs instead of 16), for quantities whose
/// range and needed resolution fit 16 bits (FILTER.md, "Q formats"). Saturating like Fixed.
template <int F>
class Fixed16 {
 public:
  static_assert(F > 0 && F < 15, "Fixed16<F>: F fraction bits, 1..14");
  static constexpr int kFractionBits = F;
  constexpr Fixed16() : raw_(0) {}
  /// From an integer: Eigen-style Scalar(0); |v| < 2^(15 - F).
  constexpr explicit Fixed16(int v) : raw_(static_cast<int16_t>(v * (1 << F))) {}
  static constexpr Fixed16 FromRaw(int16_t raw) { return Fixed16(raw, RawTag()); }
  constexpr int16_t raw() const { return raw_; }
  float ToFloat() const { return static_cast<float>(raw_) * (1.0f / static_cast<float>(1 << F)); }
  friend Fixed16 operator+(Fixed16 a, Fixed16 b) {
    return FromRaw(Saturate16(static_cast<int32_t>(a.raw_) + b.raw_));
  }
  friend Fixed16 operator-(Fixed16 a) { return FromRaw(Saturate16(-static_cast<int32_t>(a.raw_))); }
  friend constexpr bool operator==(Fixed16 a, Fixed16 b) { return a.raw_ == b.raw_; }
  friend constexpr bool operator!=(Fixed16 a, Fixed16 b) { return a.raw_ != b.raw_; }

  /// v saturated to int16 (counted). (The bounds as int32: on AVR -0x8000 is an unsigned int.)
  static JA_FORCE_INLINE int16_t Saturate16(int32_t v) {
    constexpr int32_t kMax = INT16_MAX, kMin = INT16_MIN;
    if (v > kMax) {
      ++SaturationCount();
      return INT16_MAX;
    }
    if (v < kMin) {
      ++SaturationCount();
      return INT16_MIN;
    }
    return static_cast<int16_t>(v);
  }

 private:
  struct RawTag {};
  constexpr Fixed16(int16_t raw, RawTag) : raw_(raw) {}
  int16_t raw_;
};

/// float everywhere: the reference build of the same filter source (and its cycle baseline).
struct FloatPolicy {
  using Accel = float;    // m/s^2: readings, z, h, innovations (1/s^2 in the omega^2 rows)
  using Coef = float;     // array matrices G, F (1/m, 1)
  using DtCoef = float;   // dt G_alpha (s/m)
  using Omega = float;    // rad/s
  using Angle = float;    // rad; also sin/cos
  using Time = float;     // s
  using Cov = float;      // covariance P and the process noise q
  using Noise = float;    // measurement noise R_k entries, D, decorrelation factors L, s
  using Row = float;      // decorrelated Jacobian rows H~
  using Factor = float;   // decorrelation factors l of R_k = L D L^T
  using Cross = float;    // p = P H~^T
  using Inverse = float;  // 1/s, 1/D
  using Gain = float;     // k = p / s
};

/// The firmware's formats, Q(31-F).F with F below (range and resolution in FILTER.md).
struct FixedPolicy {
  using Accel = Fixed<16>;     // Q15.16  |a| < 32768 m/s^2, lsb 1.5e-5
  using Coef = Fixed<24>;      // Q7.24   |G|, |F| < 128 (arrays wider than ~1.5 cm)
  using DtCoef = Fixed<28>;    // Q3.28   |dt G_alpha| < 8, lsb 3.7e-9
  using Omega = Fixed<24>;     // Q7.24   |w| < 128 rad/s
  using Angle = Fixed<28>;     // Q3.28   theta in (-pi, pi], sin/cos, lsb 3.7e-9 rad
  using Time = Fixed<30>;      // Q1.30   dt < 2 s
  using Cov = Fixed<30>;       // Q1.30   |P| < 2 (P0 <= 1), lsb 9.3e-10
  using Noise = Fixed<24>;     // Q7.24   R, D, s < 128
  using Row = Fixed<20>;       // Q11.20  |H~| < 2048
  using Factor = Fixed16<10>;  // Q5.10   l of L (int16: 32x16 products), |l| < 32, lsb 9.8e-4
  using Cross = Fixed<24>;     // Q7.24   |P H~^T| < 128
  using Inverse = Fixed<16>;   // Q15.16  1/s, 1/D < 32768 (s, D > 3.1e-5)
  using Gain = Fixed<24>;      // Q7.24   |k| < 128
};

namespace detail {

// 64-bit intermediates are kept as {lo, hi} 32-bit words (Wide, fixed_point.hpp): avr-gcc 5.4
// turns uint64_t shifts into bit-by-bit library loops, while word shifts by a constant become
// byte moves plus a few single-bit shifts (measured: FILTER.md, "Cycles").

/// w += v (modulo 2^64). On AVR one add/adc chain (8 cycles; the C carry test costs ~20).
JA_FORCE_INLINE void AddWide(Wide& w, Wide v) {
#if defined(__AVR__)
  uint32_t lo = w.lo;
  uint32_t hi = static_cast<uint32_t>(w.hi);
  asm("add %A0, %A2\n\t"
      "adc %B0, %B2\n\t"
      "adc %C0, %C2\n\t"
      "adc %D0, %D2\n\t"
      "adc %A1, %A3\n\t"
      "adc %B1, %B3\n\t"
      "adc %C1, %C3\n\t"
      "adc %D1, %D3"
      : "+r"(lo), "+r"(hi)
      : "r"(v.lo), "r"(static_cast<uint32_t>(v.hi)));
  w.lo = lo;
  w.hi = static_cast<int32_t>(hi);
#else
  const uint32_t lo = w.lo + v.lo;
  w.hi = static_cast<int32_t>(static_cast<uint32_t>(w.hi) + static_cast<uint32_t>(v.hi) +
                              (lo < v.lo ? 1u : 0u));
  w.lo = lo;
#endif
}

/// w -= v (modulo 2^64).
JA_FORCE_INLINE void SubtractWide(Wide& w, Wide v) {
#if defined(__AVR__)
  uint32_t lo = w.lo;
  uint32_t hi = static_cast<uint32_t>(w.hi);
  asm("sub %A0, %A2\n\t"
      "sbc %B0, %B2\n\t"
      "sbc %C0, %C2\n\t"
      "sbc %D0, %D2\n\t"
      "sbc %A1, %A3\n\t"
      "sbc %B1, %B3\n\t"
      "sbc %C1, %C3\n\t"
      "sbc %D1, %D3"
      : "+r"(lo), "+r"(hi)
      : "r"(v.lo), "r"(static_cast<uint32_t>(v.hi)));
  w.lo = lo;
  w.hi = static_cast<int32_t>(hi);
#else
  const uint32_t lo = w.lo - v.lo;
  w.hi = static_cast<int32_t>(static_cast<uint32_t>(w.hi) - static_cast<uint32_t>(v.hi) -
                              (w.lo < v.lo ? 1u : 0u));
  w.lo = lo;
#endif
}

#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
/// Columns 0-2 of the column multiply-accumulate (byte products a_i b_j, i + j <= 2, carries
/// counted in [t]): the start of JA_AVR_MAC32_BODY and of MacWideB24's 24-bit path alike.
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

/// MacWide's kernel on AVR (below): the 32x32 column multiply-accumulate and its sign
/// corrections, labels 1 and 2, operands [lo], [hi], [t], [a], [b], [z]; also the full-width
/// path of MacWideB24.
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
#endif

/// acc += a * b (signed, modulo 2^64) with the product scanned straight into the accumulator,
/// column by column (byte products a_i b_j with i + j = c): each is added at bytes c, c + 1 and
/// its carry counted in one register t; at the end of the column t is added at byte c + 2 and
/// the carry of that add becomes the next column's t. So the kernel needs the accumulator, the
/// operands, t and a zero register (no 8-byte temporary; the product-then-add form runs out of
/// AVR registers inside a sum), and no carry ripples to the top per product (the former form
/// did: 96 add/adc per MAC, now 64). Unsigned bytes, then the sign correction
/// hi -= (a < 0 ? b : 0) + (b < 0 ? a : 0).
JA_FORCE_INLINE void MacWide(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
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
#else
  AddWide(acc, MultiplyWide(a, b));
#endif
}

/// MacWide with a test of b's width first: when b fits 24 bits (byte 3 is the sign of byte 2:
/// the readings, |a| < 128 m/s^2 in Q15.16) its 4 MULs with byte 3 are left out, 12 instead of
/// 16, and b's sign is corrected at byte 3 (b = ub - 2^24 [b < 0]); else the full product. The
/// same value either way (x86: the int64 product). For the link rows (TermsKernel), whose
/// readings nearly always fit: ~20 cycles less a term, 5 more when b does not fit.
JA_FORCE_INLINE void MacWideB24(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
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
#else
  AddWide(acc, MultiplyWide(a, b));
#endif
}

/// acc += a * b (signed, modulo 2^64) for a 16-bit signed b: 8 MULs instead of 16. The unsigned
/// byte products ua_i ub_j by columns as in MacWide (columns 0..4, carries counted in t and
/// added once per column; the last column's carry rippled to byte 7), then the signs, with
/// a = ua - 2^32 [a < 0] and b = ub - 2^16 [b < 0]:
///   a b = ua ub - 2^16 ua [b < 0] - 2^32 b [a < 0]      (b sign-extended in the last term),
/// i.e. ua subtracted at byte 2 (6 bytes, borrow to the top) when b < 0 and b subtracted from
/// the high word when a < 0. x86 (and the reference): the int64 product added.
JA_FORCE_INLINE void MacWide32x16(Wide& acc, int32_t a, int16_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
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
#else
  AddWide(acc, MultiplyWide(a, static_cast<int32_t>(b)));
#endif
}

/// acc -= a * b (signed, modulo 2^64) for a 16-bit signed b: MacWide32x16 with sub/sbc (t counts
/// the borrows) and the sign terms added back: acc - a b = acc - ua ub + 2^16 ua [b < 0]
/// + 2^32 b [a < 0]. x86 (and the reference): the int64 product subtracted.
JA_FORCE_INLINE void MsubWide32x16(Wide& acc, int32_t a, int16_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
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
#else
  SubtractWide(acc, MultiplyWide(a, static_cast<int32_t>(b)));
#endif
}

/// acc -= a * b (signed, modulo 2^64); as MacWide with sub/sbc (t counts the borrows).
JA_FORCE_INLINE void MsubWide(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
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
#else
  SubtractWide(acc, MultiplyWide(a, b));
#endif
}

/// round(w / 2^kShift) (half up), saturated to int32; 0 <= kShift <= 32.
template <int kShift>
JA_FORCE_INLINE int32_t RoundShiftSaturate(Wide w) {
  static_assert(kShift >= 0 && kShift <= 32, "shift 0..32");
  if (kShift == 0) return SaturateWide(w.lo, w.hi);
  if (RoundShiftAsm<kShift>::kHave) {  // AVR: fixed_round_avr.hpp
    uint8_t sat;
    const int32_t r = RoundShiftAsm<kShift>::Run(w.lo, static_cast<uint32_t>(w.hi), sat);
    if (sat) ++SaturationCount();
    return r;
  }
  Wide r = w;
  AddWide(r, Wide{static_cast<uint32_t>(1) << (kShift > 0 ? kShift - 1 : 0), 0});  // + 1/2
  if (kShift == 32) return r.hi;  // |result| < 2^31 always
  r = ShiftRightWide<kShift>(r);
  return SaturateWide(r.lo, r.hi);
}

/// raw * 2^kShift as a Wide, exactly; 0 <= kShift < 32.
template <int kShift>
JA_FORCE_INLINE Wide WidenRaw(int32_t raw) {
  static_assert(kShift >= 0 && kShift < 32, "shift 0..31");
  // Whole bytes, then the remaining bits left (k % 8 <= 4) or right from the next byte up:
  // at most 4 single-bit steps.
  constexpr int kBits = kShift % 8;
  if (kBits <= 4) {
    Wide w = ShiftRightWide<32 - 8 * (kShift / 8)>(Wide{0u, raw});  // raw 2^(8 (k / 8))
    for (int i = 0; i < kBits; ++i) DoubleWide(w);
    return w;
  }
  return ShiftRightWide<32 - kShift>(Wide{0u, raw});  // raw 2^32 / 2^(32 - k)
}

/// The fixed-point types' fraction bits and width.
template <class T>
struct FixedInfo;
template <int F>
struct FixedInfo<Fixed<F>> {
  static constexpr int kF = F;
  static constexpr bool k16 = false;
  /// A rounded value (int32, already saturated to 32 bits) as this type.
  static JA_FORCE_INLINE Fixed<F> From(int32_t raw) { return Fixed<F>::FromRaw(raw); }
};
template <int F>
struct FixedInfo<Fixed16<F>> {
  static constexpr int kF = F;
  static constexpr bool k16 = true;
  static JA_FORCE_INLINE Fixed16<F> From(int32_t raw) {
    return Fixed16<F>::FromRaw(Fixed16<F>::Saturate16(raw));
  }
};

/// The exact 64-bit product a * b and its multiply-accumulate forms, by operand widths: 32x32
/// (16 MULs), 32x16 either way round (8 MULs; the 16-bit operand is b of the kernels).
template <class A, class B, bool kA16 = FixedInfo<A>::k16, bool kB16 = FixedInfo<B>::k16>
struct Product {  // 32 x 32
  static JA_FORCE_INLINE Wide Mul(A a, B b) { return MultiplyWide(a.raw(), b.raw()); }
  static JA_FORCE_INLINE void Mac(Wide& w, A a, B b) { MacWide(w, a.raw(), b.raw()); }
  static JA_FORCE_INLINE void Msub(Wide& w, A a, B b) { MsubWide(w, a.raw(), b.raw()); }
};
template <class A, class B>
struct Product<A, B, false, true> {  // 32 x 16
  static JA_FORCE_INLINE Wide Mul(A a, B b) {
    Wide w = {0u, 0};
    MacWide32x16(w, a.raw(), b.raw());
    return w;
  }
  static JA_FORCE_INLINE void Mac(Wide& w, A a, B b) { MacWide32x16(w, a.raw(), b.raw()); }
  static JA_FORCE_INLINE void Msub(Wide& w, A a, B b) { MsubWide32x16(w, a.raw(), b.raw()); }
};
template <class A, class B>
struct Product<A, B, true, false> {  // 16 x 32
  static JA_FORCE_INLINE Wide Mul(A a, B b) { return Product<B, A>::Mul(b, a); }
  static JA_FORCE_INLINE void Mac(Wide& w, A a, B b) { Product<B, A>::Mac(w, b, a); }
  static JA_FORCE_INLINE void Msub(Wide& w, A a, B b) { Product<B, A>::Msub(w, b, a); }
};
template <class A, class B>
struct Product<A, B, true, true> {  // 16 x 16, through the 32x16 kernels
  static JA_FORCE_INLINE Wide Mul(A a, B b) {
    Wide w = {0u, 0};
    MacWide32x16(w, a.raw(), b.raw());
    return w;
  }
  static JA_FORCE_INLINE void Mac(Wide& w, A a, B b) { MacWide32x16(w, a.raw(), b.raw()); }
  static JA_FORCE_INLINE void Msub(Wide& w, A a, B b) { MsubWide32x16(w, a.raw(), b.raw()); }
};

template <class R, class A, class B>
struct Arith {  // fixed-point types (Fixed, Fixed16): one exact product, one rounding
  static constexpr int kShift = FixedInfo<A>::kF + FixedInfo<B>::kF - FixedInfo<R>::kF;
  static_assert(kShift >= 0, "result format finer than the product");
  static JA_FORCE_INLINE R Mul(A a, B b) {
    return FixedInfo<R>::From(RoundShiftSaturate<kShift>(Product<A, B>::Mul(a, b)));
  }
};

template <>
struct Arith<float, float, float> {
  static JA_FORCE_INLINE float Mul(float a, float b) { return a * b; }
};

template <class R, class A>
struct Convert;

template <>
struct Convert<float, float> {
  static JA_FORCE_INLINE float Cast(float a) { return a; }
  static JA_FORCE_INLINE float Recip(float a) { return 1.0f / a; }
  static JA_FORCE_INLINE float Sqrt(float a) { return a > 0.0f ? sqrtf(a) : 0.0f; }
};

template <int Fr, int Fa>
struct Convert<Fixed<Fr>, Fixed<Fa>> {
  static JA_FORCE_INLINE Fixed<Fr> Cast(Fixed<Fa> a) { return ConvertFixed<Fr>(a); }
  /// 2^(Fr + Fa) / a (ReciprocalRaw: relative error < 2^-18, no division), saturated; a = 0
  /// saturates (counted).
  static Fixed<Fr> Recip(Fixed<Fa> a) {
    static_assert(Fr + Fa <= 61, "reciprocal scale");
    if (a.raw() == 0) {
      ++SaturationCount();
      return Fixed<Fr>::FromRaw(0x7FFFFFFF);
    }
    const bool negative = a.raw() < 0;
    const uint32_t ua =
        negative ? 0u - static_cast<uint32_t>(a.raw()) : static_cast<uint32_t>(a.raw());
    const int32_t r = ReciprocalRaw<Fr + Fa>(ua);
    return Fixed<Fr>::FromRaw(negative ? -r : r);
  }
  /// sqrt(a) for a > 0, else 0: sqrt(raw 2^(2 Fr - Fa)) (SqrtRaw), truncated.
  static Fixed<Fr> Sqrt(Fixed<Fa> a) {
    if (a.raw() <= 0) return Fixed<Fr>::FromRaw(0);
    return Fixed<Fr>::FromRaw(SqrtRaw<2 * Fr - Fa>(static_cast<uint32_t>(a.raw())));
  }
};

template <int Fr, int Fa>
struct Convert<Fixed16<Fr>, Fixed<Fa>> {
  static_assert(Fa >= Fr, "Fixed16 casts only to fewer fraction bits");
  /// round(a / 2^(Fa - Fr)) saturated to 16 bits (counted).
  static JA_FORCE_INLINE Fixed16<Fr> Cast(Fixed<Fa> a) {
    const int32_t raw = a.raw();
    return FixedInfo<Fixed16<Fr>>::From(
        RoundShiftSaturate<Fa - Fr>(Wide{static_cast<uint32_t>(raw), raw < 0 ? -1 : 0}));
  }
};

}  // namespace detail

template <class R, class A, class B>
JA_FORCE_INLINE R Mul(A a, B b) {
  return detail::Arith<R, A, B>::Mul(a, b);
}

template <class R, class A>
JA_FORCE_INLINE R Cast(A a) {
  return detail::Convert<R, A>::Cast(a);
}

template <class R, class A>
inline R Recip(A a) {
  return detail::Convert<R, A>::Recip(a);
}

/// sqrt(a) as type R for a > 0, 0 otherwise (Fixed: integer square root, truncated).
template <class R, class A>
inline R Sqrt(A a) {
  return detail::Convert<R, A>::Sqrt(a);
}

/// Several rows of a sparse linear map at once: row r is sum_j coef * in[j] over the j whose bit
/// is set in mask[r] (bit j: input j; at most 8 inputs), the rows' coefficients stored one after
/// the other in ascending j, rounded once as R into out[r]. The non-zero coefficients only
/// (Configure), so exactly the sums of the full rows, in both builds. Fixed: one out-of-line
/// kernel per format pair and row count whose 64-bit sum stays in registers: one call (and one
/// register save) for all of a link's rows, and a bit test per input instead of a test of the
/// coefficient's four bytes (AVR: one call per row with the zero tests cost ~220 cycles a row on
/// top of ~100 a term).
template <class R, class A, class B, int kRows>
struct TermsKernel;

template <int kRows>
struct TermsKernel<float, float, float, kRows> {
  static void Run(const float* coef, const uint8_t* mask, const float* in, float* out) {
    for (int r = 0; r < kRows; ++r) {
      float sum = 0.0f;
      const float* x = in;
      for (uint8_t m = mask[r]; m != 0; m = static_cast<uint8_t>(m >> 1), ++x) {
        if (m & 1u) sum += *coef++ * *x;
      }
      out[r] = sum;
    }
  }
};

template <int Fr, int Fa, int Fb, int kRows>
struct TermsKernel<Fixed<Fr>, Fixed<Fa>, Fixed<Fb>, kRows> {
  static constexpr int kShift = Fa + Fb - Fr;
  static_assert(kShift >= 0, "result format finer than the products");
  JA_NOINLINE static void Run(const Fixed<Fa>* coef, const uint8_t* mask, const Fixed<Fb>* in,
                              Fixed<Fr>* out) {
    for (int r = 0; r < kRows; ++r) {
      detail::Wide sum = {0u, 0};
      const Fixed<Fb>* x = in;
      for (uint8_t m = mask[r]; m != 0; m = static_cast<uint8_t>(m >> 1), ++x) {
        if (m & 1u) detail::MacWideB24(sum, (coef++)->raw(), x->raw());
      }
      out[r] = Fixed<Fr>::FromRaw(detail::RoundShiftSaturate<kShift>(sum));
    }
  }
};

template <int kRows, class R, class A, class B>
inline void SparseRows(const A* coef, const uint8_t* mask, const B* in, R* out) {
  TermsKernel<R, A, B, kRows>::Run(coef, mask, in, out);
}

inline float ToFloat(float v) { return v; }
template <int F>
inline float ToFloat(Fixed<F> v) {
  return v.ToFloat();
}

/// Sum of products a_i * b_i (plus terms of type R) as R, rounded once at the end.
template <class R, class A, class B>
class Sum;

template <>
class Sum<float, float, float> {
 public:
  JA_FORCE_INLINE void Add(float a, float b) { sum_ += a * b; }
  JA_FORCE_INLINE void Subtract(float a, float b) { sum_ -= a * b; }
  JA_FORCE_INLINE void AddValue(float v) { sum_ += v; }
  JA_FORCE_INLINE float Result() const { return sum_; }

 private:
  float sum_ = 0.0f;
};

template <class R, class A, class B>
class Sum {  // fixed-point types (Fixed, Fixed16)
 public:
  static constexpr int kShift =
      detail::FixedInfo<A>::kF + detail::FixedInfo<B>::kF - detail::FixedInfo<R>::kF;
  static_assert(kShift >= 0, "result format finer than the products");
  /// sum += a * b, exact (64-bit, modulo 2^64: exact for fewer than 2 terms of 2^62). The first
  /// term is the plain product (MultiplyWide: no accumulator to clear and add to); empty_ is a
  /// compile-time constant wherever the sum is a local of straight-line code.
  JA_FORCE_INLINE void Add(A a, B b) {
    if (empty_) {
      sum_ = detail::Product<A, B>::Mul(a, b);
      empty_ = false;
    } else {
      detail::Product<A, B>::Mac(sum_, a, b);
    }
  }
  JA_FORCE_INLINE void Subtract(A a, B b) {
    detail::Product<A, B>::Msub(sum_, a, b);
    empty_ = false;
  }
  /// sum += v, v already of the result type. Added after the rounding: v is a whole number of
  /// result LSBs, so round(v 2^k + S) / 2^k = v + round(S / 2^k) exactly (only the saturation
  /// point differs: the products alone saturate first), without widening v to 64 bits.
  JA_FORCE_INLINE void AddValue(R v) { offset_ = offset_ + v; }
  JA_FORCE_INLINE R Result() const {
    return detail::FixedInfo<R>::From(detail::RoundShiftSaturate<kShift>(sum_)) + offset_;
  }

 private:
  detail::Wide sum_ = {0u, 0};
  R offset_;
  bool empty_ = true;
};

}  // namespace core
}  // namespace ja
