// Q-format fixed-point scalar for the firmware core, usable as an Eigen scalar.
//
// Fixed<F> stores a real value v as the int32 raw = round(v * 2^F) ("Q(31-F).F"). Arithmetic is
// saturating and never has undefined behaviour: results outside [-2^31, 2^31 - 1] raw clamp to the
// nearest end and increment the saturation counter (SaturationCount()). Products use 64 bits only
// as an intermediate. Rounding is round-half-up everywhere (floor(x + 1/2)), identical on AVR and
// x86, so the AVR image and the x86 build agree bit for bit.
//
// AVR cost notes (measured, see NUMERICS.md): a product needs the 64-bit intermediate, which
// avr-gcc builds with a generic 64x64 libcall (~260 cycles) plus a bit-by-bit shift loop. Here the
// 32x32->64 product is 16 hardware MULs in inline assembly and the >> F is a byte move when F is a
// multiple of 8, so F in {8, 16, 24} is the fast path.
#pragma once

#include <stdint.h>

// Force inlining of the arithmetic: on AVR a call plus a struct return through the stack costs more
// than the product itself (measured: 348 vs ~110 cycles).
#define JA_FORCE_INLINE inline __attribute__((always_inline))

namespace ja {
namespace core {

/// Saturation events since the last reset (wraps at 65535). One counter for the whole core:
/// operators of an Eigen scalar cannot carry context; the filter reads and resets it per step.
inline uint16_t& SaturationCount() {
  static uint16_t count = 0;
  return count;
}

namespace detail {

/// 64-bit product a * b as {lo, hi} words: a * b = hi * 2^32 + lo (hi signed).
struct Wide {
  uint32_t lo;
  int32_t hi;
};

JA_FORCE_INLINE Wide MultiplyWide(int32_t a, int32_t b) {
#if defined(__AVR__) && defined(__AVR_HAVE_MUL__)
  // Unsigned 32x32->64 by columns (schoolbook on bytes, 16 MULs), then the signed correction
  // a*b = ua*ub - 2^32 * ((a<0 ? ub : 0) + (b<0 ? ua : 0))  (mod 2^64).
  // Column order bounds every carry to two bytes above the product (checked exhaustively over
  // byte patterns and 2e5 random pairs when written).
  uint32_t lo;
  uint32_t hi;
  const uint8_t zero = 0;
  asm("\n\t"
      "clr %A0\n\t"
      "clr %B0\n\t"
      "clr %C0\n\t"
      "clr %D0\n\t"
      "clr %A1\n\t"
      "clr %B1\n\t"
      "clr %C1\n\t"
      "clr %D1\n\t"
      "mul %A2, %A3\n\t"
      "add %A0, r0\n\t"
      "adc %B0, r1\n\t"
      "adc %C0, %4\n\t"
      "mul %A2, %B3\n\t"
      "add %B0, r0\n\t"
      "adc %C0, r1\n\t"
      "adc %D0, %4\n\t"
      "mul %B2, %A3\n\t"
      "add %B0, r0\n\t"
      "adc %C0, r1\n\t"
      "adc %D0, %4\n\t"
      "mul %A2, %C3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %B2, %B3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %C2, %A3\n\t"
      "add %C0, r0\n\t"
      "adc %D0, r1\n\t"
      "adc %A1, %4\n\t"
      "mul %A2, %D3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %B2, %C3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %C2, %B3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %D2, %A3\n\t"
      "add %D0, r0\n\t"
      "adc %A1, r1\n\t"
      "adc %B1, %4\n\t"
      "mul %B2, %D3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %C2, %C3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %D2, %B3\n\t"
      "add %A1, r0\n\t"
      "adc %B1, r1\n\t"
      "adc %C1, %4\n\t"
      "mul %C2, %D3\n\t"
      "add %B1, r0\n\t"
      "adc %C1, r1\n\t"
      "adc %D1, %4\n\t"
      "mul %D2, %C3\n\t"
      "add %B1, r0\n\t"
      "adc %C1, r1\n\t"
      "adc %D1, %4\n\t"
      "mul %D2, %D3\n\t"
      "add %C1, r0\n\t"
      "adc %D1, r1\n\t"
      "clr __zero_reg__\n\t"
      : "=&r"(lo), "=&r"(hi)
      : "r"(a), "r"(b), "r"(zero)
      : "r0");
  if (a < 0) hi -= static_cast<uint32_t>(b);
  if (b < 0) hi -= static_cast<uint32_t>(a);
  return Wide{lo, static_cast<int32_t>(hi)};
#else
  const int64_t p = static_cast<int64_t>(a) * static_cast<int64_t>(b);
  const uint64_t u = static_cast<uint64_t>(p);
  return Wide{static_cast<uint32_t>(u), static_cast<int32_t>(static_cast<uint32_t>(u >> 32))};
#endif
}

/// Saturates a 64-bit value given as {lo, hi} to int32, counting saturations.
JA_FORCE_INLINE int32_t SaturateWide(uint32_t lo, int32_t hi) {
  // Representable iff hi is the sign extension of lo's top bit.
  if (hi == 0 && lo <= 0x7FFFFFFFu) return static_cast<int32_t>(lo);
  if (hi == -1 && lo >= 0x80000000u) return static_cast<int32_t>(lo - 0x80000000u) - 0x7FFFFFFF - 1;
  ++SaturationCount();
  return hi < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
}

/// round(a * b / 2^F), saturated: (a*b + 2^(F-1)) >> F.
template <int F>
JA_FORCE_INLINE int32_t MultiplyQ(int32_t a, int32_t b) {
  static_assert(F > 0 && F < 32, "fraction bits must be 1..31");
  Wide p = MultiplyWide(a, b);
  // + 2^(F-1) with carry into hi (hi cannot overflow: |a*b| <= 2^62).
  const uint32_t half = static_cast<uint32_t>(1) << (F - 1);
  const uint32_t lo = p.lo + half;
  int32_t hi = p.hi + (lo < half ? 1 : 0);
  // Arithmetic >> F of the 64-bit value, as word shifts (byte moves on AVR when F % 8 == 0).
  const uint32_t r_lo = (lo >> F) | (static_cast<uint32_t>(hi) << (32 - F));
  // r_hi = hi >> F (arithmetic), written without shifting a negative value.
  const int32_t r_hi = hi < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(hi) >> F)
                              : static_cast<int32_t>(static_cast<uint32_t>(hi) >> F);
  return SaturateWide(r_lo, r_hi);
}

// __builtin_*_overflow: measured faster in context on avr-gcc 5.4 than a hand-written sign test
// (EKF spike step 70.1 k vs 73.2 k cycles), because of register pressure around the branch.
JA_FORCE_INLINE int32_t AddSaturating(int32_t a, int32_t b) {
  int32_t r;
  if (__builtin_add_overflow(a, b, &r)) {
    ++SaturationCount();
    return a < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
  }
  return r;
}

JA_FORCE_INLINE int32_t SubtractSaturating(int32_t a, int32_t b) {
  int32_t r;
  if (__builtin_sub_overflow(a, b, &r)) {
    ++SaturationCount();
    return a < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF;
  }
  return r;
}

/// round(a * 2^F / b), saturated; b == 0 saturates towards the sign of a (0/0 -> 0, counted).
template <int F>
inline int32_t DivideQ(int32_t a, int32_t b) {
  if (b == 0) {
    ++SaturationCount();
    return a > 0 ? 0x7FFFFFFF : a < 0 ? (-0x7FFFFFFF - 1) : 0;
  }
  // |a| * 2^F / |b| in unsigned 64-bit, rounded half up in magnitude, sign applied after.
  const bool negative = (a < 0) != (b < 0);
  const uint64_t ua =
      a < 0 ? 0u - static_cast<uint64_t>(static_cast<int64_t>(a)) : static_cast<uint64_t>(a);
  const uint64_t ub =
      b < 0 ? 0u - static_cast<uint64_t>(static_cast<int64_t>(b)) : static_cast<uint64_t>(b);
  const uint64_t q = ((ua << F) + (ub >> 1)) / ub;
  if (!negative) {
    if (q > 0x7FFFFFFFu) {
      ++SaturationCount();
      return 0x7FFFFFFF;
    }
    return static_cast<int32_t>(q);
  }
  if (q > 0x80000000u) {
    ++SaturationCount();
    return -0x7FFFFFFF - 1;
  }
  return static_cast<int32_t>(0u - static_cast<uint32_t>(q));
}

}  // namespace detail

/// A real number in Q(31-F).F: raw int32 = round(value * 2^F).
template <int F>
class Fixed {
 public:
  static_assert(F > 0 && F < 31, "Fixed<F>: F fraction bits, 1..30");
  static constexpr int kFractionBits = F;
  static constexpr int32_t kOneRaw = static_cast<int32_t>(1) << F;

  constexpr Fixed() : raw_(0) {}
  /// From an integer (saturating). Explicit: Eigen writes Scalar(0), Scalar(1).
  constexpr explicit Fixed(int v) : raw_(FromInt(v)) {}
  /// From a float (round half up, saturating; NaN -> 0). For configuration, not the hot path.
  explicit Fixed(float v) : raw_(FromFloat(v)) {}
  explicit Fixed(double v) : raw_(FromFloat(static_cast<float>(v))) {}

  static constexpr Fixed FromRaw(int32_t raw) { return Fixed(raw, RawTag()); }
  constexpr int32_t raw() const { return raw_; }
  float ToFloat() const { return static_cast<float>(raw_) * (1.0f / static_cast<float>(kOneRaw)); }
  explicit operator float() const { return ToFloat(); }

  friend Fixed operator+(Fixed a, Fixed b) {
    return FromRaw(detail::AddSaturating(a.raw_, b.raw_));
  }
  friend Fixed operator-(Fixed a, Fixed b) {
    return FromRaw(detail::SubtractSaturating(a.raw_, b.raw_));
  }
  friend Fixed operator-(Fixed a) { return FromRaw(detail::SubtractSaturating(0, a.raw_)); }
  friend Fixed operator*(Fixed a, Fixed b) { return FromRaw(detail::MultiplyQ<F>(a.raw_, b.raw_)); }
  friend Fixed operator/(Fixed a, Fixed b) { return FromRaw(detail::DivideQ<F>(a.raw_, b.raw_)); }
  Fixed& operator+=(Fixed b) { return *this = *this + b; }
  Fixed& operator-=(Fixed b) { return *this = *this - b; }
  Fixed& operator*=(Fixed b) { return *this = *this * b; }
  Fixed& operator/=(Fixed b) { return *this = *this / b; }
  friend constexpr bool operator==(Fixed a, Fixed b) { return a.raw_ == b.raw_; }
  friend constexpr bool operator!=(Fixed a, Fixed b) { return a.raw_ != b.raw_; }
  friend constexpr bool operator<(Fixed a, Fixed b) { return a.raw_ < b.raw_; }
  friend constexpr bool operator>(Fixed a, Fixed b) { return a.raw_ > b.raw_; }
  friend constexpr bool operator<=(Fixed a, Fixed b) { return a.raw_ <= b.raw_; }
  friend constexpr bool operator>=(Fixed a, Fixed b) { return a.raw_ >= b.raw_; }

 private:
  struct RawTag {};
  constexpr Fixed(int32_t raw, RawTag) : raw_(raw) {}
  static constexpr int32_t FromInt(int v) {
    // v * 2^F saturated; int is 16 bits on AVR, 32 on x86.
    return static_cast<int32_t>(v) > (0x7FFFFFFF >> F) ? 0x7FFFFFFF
           : static_cast<int32_t>(v) < ((-0x7FFFFFFF - 1) >> F)
               ? (-0x7FFFFFFF - 1)
               : static_cast<int32_t>(static_cast<uint32_t>(v) << F);
  }
  static int32_t FromFloat(float v) {
    const float scaled = v * static_cast<float>(kOneRaw) + 0.5f;
    if (!(scaled == scaled)) return 0;                    // NaN
    if (scaled >= 2147483648.0f) return 0x7FFFFFFF;       // also +inf
    if (scaled < -2147483648.0f) return -0x7FFFFFFF - 1;  // also -inf
    // floor() without libm: truncate, then step down for negative non-integers.
    int32_t t = static_cast<int32_t>(scaled);
    if (static_cast<float>(t) > scaled) --t;
    return t;
  }
  int32_t raw_;
};

/// Sum of products with one rounding: the 64-bit products are added exactly and rounded and
/// saturated once in Result() (a dot product costs one rounding instead of one per term, and
/// no per-term saturation test). Float has the same interface (scalar_math.hpp), so filter code
/// written with accumulators instantiates with both.
template <class S>
class Accumulator;

template <int F>
class Accumulator<Fixed<F>> {
 public:
  /// sum += a * b (exact, 64-bit; wraps only beyond 2^63, i.e. never for 2^31-bounded terms
  /// summed fewer than 2 times).
  JA_FORCE_INLINE void Add(Fixed<F> a, Fixed<F> b) {
    const detail::Wide p = detail::MultiplyWide(a.raw(), b.raw());
    AddWide(p.lo, p.hi);
  }
  /// sum -= a * b.
  JA_FORCE_INLINE void Subtract(Fixed<F> a, Fixed<F> b) {
    const detail::Wide p = detail::MultiplyWide(a.raw(), b.raw());
    // -(hi:lo) = (~hi + carry):(~lo + 1)
    const uint32_t lo = ~p.lo + 1u;
    const int32_t hi = static_cast<int32_t>(~static_cast<uint32_t>(p.hi) + (lo == 0 ? 1u : 0u));
    AddWide(lo, hi);
  }
  /// sum += v (v scaled up by 2^F to the product scale).
  JA_FORCE_INLINE void AddValue(Fixed<F> v) {
    const uint32_t raw = static_cast<uint32_t>(v.raw());
    AddWide(raw << F, v.raw() < 0 ? static_cast<int32_t>(~(~raw >> (32 - F)))
                                  : static_cast<int32_t>(raw >> (32 - F)));
  }
  /// round(sum / 2^F), saturated (counted).
  Fixed<F> Result() const {
    const uint32_t half = static_cast<uint32_t>(1) << (F - 1);
    const uint32_t lo = lo_ + half;
    const int32_t hi = static_cast<int32_t>(static_cast<uint32_t>(hi_) + (lo < half ? 1u : 0u));
    const uint32_t r_lo = (lo >> F) | (static_cast<uint32_t>(hi) << (32 - F));
    const int32_t r_hi = hi < 0 ? -1 - static_cast<int32_t>(~static_cast<uint32_t>(hi) >> F)
                                : static_cast<int32_t>(static_cast<uint32_t>(hi) >> F);
    return Fixed<F>::FromRaw(detail::SaturateWide(r_lo, r_hi));
  }

 private:
  JA_FORCE_INLINE void AddWide(uint32_t lo, int32_t hi) {
    const uint32_t sum = lo_ + lo;
    hi_ = static_cast<int32_t>(static_cast<uint32_t>(hi_) + static_cast<uint32_t>(hi) +
                               (sum < lo ? 1u : 0u));  // modulo 2^64, no signed overflow
    lo_ = sum;
  }
  uint32_t lo_ = 0;
  int32_t hi_ = 0;
};

template <int F>
inline Fixed<F> abs(Fixed<F> x) {
  return x.raw() < 0 ? -x : x;
}

/// Re-expresses x with G fraction bits (round half up when dropping bits, saturating).
template <int G, int F>
inline Fixed<G> ConvertFixed(Fixed<F> x) {
  if (G == F) return Fixed<G>::FromRaw(x.raw());
  if (G < F) {
    constexpr int kShift = (F - G) > 0 ? (F - G) : 1;
    const int64_t r = (static_cast<int64_t>(x.raw()) + (static_cast<int64_t>(1) << (kShift - 1)));
    const uint64_t u = static_cast<uint64_t>(r);
    const int32_t hi = static_cast<int32_t>(static_cast<uint32_t>(u >> 32));
    // arithmetic >> kShift on the {lo, hi} pair
    const uint32_t lo = static_cast<uint32_t>(u);
    const uint32_t r_lo = (lo >> kShift) | (static_cast<uint32_t>(hi) << (32 - kShift));
    const int32_t r_hi = hi < 0 ? -1 : 0;
    return Fixed<G>::FromRaw(detail::SaturateWide(r_lo, r_hi));
  }
  constexpr int kShift = (G - F) > 0 ? (G - F) : 1;
  const int32_t limit = static_cast<int32_t>(0x7FFFFFFF >> kShift);
  if (x.raw() > limit || x.raw() < -limit - 1) {
    ++SaturationCount();
    return Fixed<G>::FromRaw(x.raw() < 0 ? (-0x7FFFFFFF - 1) : 0x7FFFFFFF);
  }
  return Fixed<G>::FromRaw(static_cast<int32_t>(static_cast<uint32_t>(x.raw()) << kShift));
}

}  // namespace core
}  // namespace ja
