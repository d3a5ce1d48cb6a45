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
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
#include "fixed_mac_avr.hpp"  // MacWide and its kin in assembly
#endif
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
  using Lag = float;      // tau / dt of a sensor's read (AlignReadings)
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
  using Lag = Fixed16<14>;     // Q1.14   tau / dt in [-1, 1] (int16: 32x16 products), lsb 6.1e-5
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

/// acc += a * b (signed, modulo 2^64). On AVR the column kernel of fixed_mac_avr.hpp (16 MULs).
JA_FORCE_INLINE void MacWide(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  MacWideAsm(acc, a, b);
#else
  AddWide(acc, MultiplyWide(a, b));
#endif
}

/// acc += a * b (signed, modulo 2^64) for the link rows (TermsKernel), whose b (the readings)
/// nearly always fits 24 bits: on AVR 12 MULs then, 16 when it does not (fixed_mac_avr.hpp).
/// The same value either way.
JA_FORCE_INLINE void MacWideB24(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  MacWideB24Asm(acc, a, b);
#else
  AddWide(acc, MultiplyWide(a, b));
#endif
}

/// acc += a * b (signed, modulo 2^64) for a 16-bit signed b: on AVR 8 MULs instead of 16
/// (fixed_mac_avr.hpp).
JA_FORCE_INLINE void MacWide32x16(Wide& acc, int32_t a, int16_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  MacWide32x16Asm(acc, a, b);
#else
  AddWide(acc, MultiplyWide(a, static_cast<int32_t>(b)));
#endif
}

/// acc -= a * b (signed, modulo 2^64) for a 16-bit signed b (AVR: 8 MULs, fixed_mac_avr.hpp).
JA_FORCE_INLINE void MsubWide32x16(Wide& acc, int32_t a, int16_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  MsubWide32x16Asm(acc, a, b);
#else
  SubtractWide(acc, MultiplyWide(a, static_cast<int32_t>(b)));
#endif
}

/// acc -= a * b (signed, modulo 2^64) (AVR: fixed_mac_avr.hpp).
JA_FORCE_INLINE void MsubWide(Wide& acc, int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  MsubWideAsm(acc, a, b);
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
