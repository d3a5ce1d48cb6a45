// Fixed-point edge cases (saturation, rounding, no UB: this binary runs under UBSan/ASan), the
// CORDIC-free trig against libm, Eigen with Fixed as scalar, and the EKF spike float vs fixed.
#include <cmath>
#include <cstdint>
#include <limits>

#include "check.hpp"
#include "core/fixed_eigen.hpp"
#include "core/fixed_trig.hpp"
#include "core/numeric_policy.hpp"
#include "platform/avr/bench/ekf_spike.hpp"

using Q16 = ja::core::Fixed<16>;
using Q24 = ja::core::Fixed<24>;
using ja::core::SaturationCount;

namespace {

constexpr int32_t kMax = std::numeric_limits<int32_t>::max();
constexpr int32_t kMin = std::numeric_limits<int32_t>::min();

// Reference: round-half-up of a*b/2^F in exact 128-bit-free arithmetic (|a*b| < 2^63).
int64_t ReferenceMultiply(int32_t a, int32_t b, int f) {
  const int64_t p = static_cast<int64_t>(a) * b;
  const int64_t q = (p + (int64_t{1} << (f - 1))) >> f;  // arithmetic shift (C++20, GCC)
  return q;
}

void TestMultiply() {
  uint32_t lcg = 1;
  for (int i = 0; i < 200000; ++i) {
    lcg = lcg * 1664525u + 1013904223u;
    const int32_t a = static_cast<int32_t>(lcg) >> (i % 31);
    lcg = lcg * 1664525u + 1013904223u;
    const int32_t b = static_cast<int32_t>(lcg) >> ((i / 31) % 31);
    SaturationCount() = 0;
    const int64_t ref = ReferenceMultiply(a, b, 16);
    const int32_t got = (Q16::FromRaw(a) * Q16::FromRaw(b)).raw();
    const int64_t clamped = ref > kMax ? kMax : ref < kMin ? kMin : ref;
    if (!CHECK_EQ(static_cast<int64_t>(got), clamped)) break;
    CHECK_EQ(SaturationCount(), (ref != clamped) ? 1u : 0u);
    const int64_t ref24 = ReferenceMultiply(a, b, 24);
    const int64_t c24 = ref24 > kMax ? kMax : ref24 < kMin ? kMin : ref24;
    if (!CHECK_EQ(static_cast<int64_t>((Q24::FromRaw(a) * Q24::FromRaw(b)).raw()), c24)) break;
  }
  // Exact values and rounding: 1.5 * -2.25 = -3.375; half-LSB rounds up.
  CHECK_EQ((Q16(1.5f) * Q16(-2.25f)).raw(), Q16(-3.375f).raw());
  CHECK_EQ((Q16::FromRaw(1) * Q16::FromRaw(0x8000)).raw(), 1);   // 0.5 LSB -> up
  CHECK_EQ((Q16::FromRaw(-1) * Q16::FromRaw(0x8000)).raw(), 0);  // -0.5 LSB -> up (to 0)
  SaturationCount() = 0;
  CHECK_EQ((Q16::FromRaw(kMin) * Q16::FromRaw(kMin)).raw(), kMax);
  CHECK_EQ((Q16::FromRaw(kMax) * Q16::FromRaw(kMin)).raw(), kMin);
  CHECK_EQ(SaturationCount(), 2u);
}

void TestAccumulator() {
  uint32_t lcg = 7;
  for (int i = 0; i < 20000; ++i) {
    ja::core::Accumulator<Q16> acc;
    __int128 exact = 0;
    for (int k = 0; k < 4; ++k) {
      lcg = lcg * 1664525u + 1013904223u;
      const int32_t a = static_cast<int32_t>(lcg) >> (i % 29);
      lcg = lcg * 1664525u + 1013904223u;
      const int32_t b = static_cast<int32_t>(lcg) >> ((i + k) % 27);
      if (k == 2) {
        acc.Subtract(Q16::FromRaw(a), Q16::FromRaw(b));
        exact -= static_cast<__int128>(a) * b;
      } else {
        acc.Add(Q16::FromRaw(a), Q16::FromRaw(b));
        exact += static_cast<__int128>(a) * b;
      }
    }
    acc.AddValue(Q16::FromRaw(-12345));
    exact += static_cast<__int128>(-12345) * 65536;
    // floor((exact + 2^15) / 2^16) on the value the 64-bit accumulator holds (mod 2^64).
    const int64_t held = static_cast<int64_t>(static_cast<uint64_t>(exact));
    const __int128 q = (static_cast<__int128>(held) + 32768) >> 16;
    const int64_t want = q > kMax ? kMax : q < kMin ? kMin : static_cast<int64_t>(q);
    if (!CHECK_EQ(static_cast<int64_t>(acc.Result().raw()), want)) break;
  }
  ja::core::Accumulator<Q16> small;
  small.Add(Q16(1.5f), Q16(2.0f));
  small.Subtract(Q16(0.5f), Q16(1.0f));
  small.AddValue(Q16(0.25f));
  CHECK_EQ(small.Result().raw(), Q16(2.75f).raw());
}

void TestAddSubtractNegate() {
  SaturationCount() = 0;
  CHECK_EQ((Q16::FromRaw(kMax) + Q16::FromRaw(1)).raw(), kMax);
  CHECK_EQ((Q16::FromRaw(kMin) - Q16::FromRaw(1)).raw(), kMin);
  CHECK_EQ((-Q16::FromRaw(kMin)).raw(), kMax);
  CHECK_EQ(SaturationCount(), 3u);
  CHECK_EQ((Q16(2) + Q16(-3)).raw(), -65536);
  CHECK_EQ(ja::core::abs(Q16(-2.5f)).raw(), Q16(2.5f).raw());
}

void TestDivide() {
  CHECK_EQ((Q16(3) / Q16(2)).raw(), Q16(1.5f).raw());
  CHECK_EQ((Q16(-1) / Q16(3)).raw(), -21845);  // -0.33333 rounds half away in magnitude
  SaturationCount() = 0;
  CHECK_EQ((Q16(1) / Q16()).raw(), kMax);
  CHECK_EQ((Q16(-1) / Q16()).raw(), kMin);
  CHECK_EQ((Q16() / Q16()).raw(), 0);
  CHECK_EQ((Q16(30000) / Q16::FromRaw(1)).raw(), kMax);
  CHECK_EQ((Q16::FromRaw(kMin) / Q16(-1)).raw(), kMax);
  CHECK_EQ(SaturationCount(), 5u);
}

void TestConversions() {
  SaturationCount() = 0;
  CHECK_EQ(Q16(1e9f).raw(), kMax);
  CHECK_EQ(Q16(-1e9f).raw(), kMin);
  CHECK_EQ(Q16(std::numeric_limits<float>::quiet_NaN()).raw(), 0);
  CHECK_EQ(Q16(std::numeric_limits<float>::infinity()).raw(), kMax);
  CHECK_EQ(Q16(-0.5f / 65536).raw(), 0);  // -0.5 LSB rounds up
  CHECK_EQ(Q16(40000).raw(), kMax);
  CHECK_EQ(Q16(-40000).raw(), kMin);
  CHECK_NEAR(Q16(3.14159f).ToFloat(), 3.14159, 1.0 / 65536);
  CHECK_EQ((ja::core::ConvertFixed<24>(Q16(1.25f))).raw(), Q24(1.25f).raw());
  CHECK_EQ((ja::core::ConvertFixed<16>(Q24::FromRaw(0x80))).raw(), 1);  // half rounds up
  CHECK_EQ((ja::core::ConvertFixed<24>(Q16(200))).raw(), kMax);
}

void TestTrig() {
  double worst_sin = 0, worst_atan = 0;
  for (int i = -4000; i <= 4000; ++i) {
    const double angle = i * 0.0031;  // about +-12.4 rad
    const Q16 a(static_cast<float>(angle));
    const double exact = static_cast<double>(a.raw()) / 65536.0;
    worst_sin = std::fmax(worst_sin, std::fabs(ja::core::Sin(a).ToFloat() - std::sin(exact)));
    worst_sin = std::fmax(worst_sin, std::fabs(ja::core::Cos(a).ToFloat() - std::cos(exact)));
  }
  CHECK(worst_sin < 2.5e-5);  // 1 LSB of Q16 + 5e-6 interpolation
  for (int i = 0; i < 3600; ++i) {
    const double t = i * (2 * M_PI / 3600);
    for (double r : {1e-3, 0.37, 5.0, 20000.0}) {
      const Q16 y(static_cast<float>(r * std::sin(t))), x(static_cast<float>(r * std::cos(t)));
      const double exact = std::atan2(y.raw() * 1.0, x.raw() * 1.0);
      double err = std::fabs(ja::core::Atan2(y, x).ToFloat() - exact);
      err = std::fmin(err, 2 * M_PI - err);
      worst_atan = std::fmax(worst_atan, err);
    }
  }
  CHECK(worst_atan < 1e-4);
  CHECK_EQ(ja::core::Atan2(Q16(), Q16()).raw(), 0);
  CHECK_NEAR(ja::core::Atan2(Q16(), Q16(-1)).ToFloat(), M_PI, 2e-5);
  CHECK_NEAR(ja::core::Atan2(Q16(-1), Q16()).ToFloat(), -M_PI / 2, 2e-5);
  // Q24 too (different output shift).
  CHECK_NEAR(ja::core::Sin(Q24(0.5f)).ToFloat(), std::sin(0.5), 1e-5);
  CHECK_NEAR(ja::core::Atan2(Q24(1.0f), Q24(1.0f)).ToFloat(), M_PI / 4, 1e-5);
}

void TestEigenWithFixed() {
  Eigen::Matrix<Q16, 3, 3> a;
  Eigen::Matrix<float, 3, 3> af;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      af(i, j) = 0.25f * static_cast<float>(i) - 0.5f * static_cast<float>(j) + 0.125f;
      a(i, j) = Q16(af(i, j));
    }
  }
  const Eigen::Matrix<Q16, 3, 3> p = a * a.transpose() + Eigen::Matrix<Q16, 3, 3>::Identity();
  const Eigen::Matrix<float, 3, 3> pf = af * af.transpose() + Eigen::Matrix3f::Identity();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) CHECK_NEAR(p(i, j).ToFloat(), pf(i, j), 1e-4);
  }
  const Eigen::Matrix<Q16, 3, 1> v = a.col(1) - a.col(0);
  CHECK_NEAR(v.dot(v).ToFloat(), (af.col(1) - af.col(0)).squaredNorm(), 1e-4);
}

}  // namespace

// IntegerSqrt is floor(sqrt(v)) over random and edge values; SqrtRaw<k> = sqrt(a 2^k) truncated
// to a 16-bit root (relative error < 2^-15, plus 1 LSB); through the policy sqrt(Q15.16) ->
// Q7.24, 0 for a <= 0.
void TestSqrt() {
  SaturationCount() = 0;
  uint32_t x = 987654321u;
  for (int i = 0; i < 20000; ++i) {
    x = x * 1664525u + 1013904223u;
    const uint32_t v = x >> (i % 32);
    const uint32_t r = ja::core::detail::IntegerSqrt(v);
    const uint64_t r64 = r;
    if (!CHECK(r64 * r64 <= v && (r64 + 1) * (r64 + 1) > v)) break;
  }
  CHECK_EQ(ja::core::detail::IntegerSqrt(0u), 0u);
  CHECK_EQ(ja::core::detail::IntegerSqrt(0xFFFFFFFFu), 65535u);
  for (int i = 0; i < 5000; ++i) {
    x = x * 1664525u + 1013904223u;
    const uint32_t a = (x >> (i % 31 + 1)) | 1u;  // < 2^31
    const double want = std::sqrt(static_cast<double>(a) * std::ldexp(1.0, 32));
    if (want >= 2147483647.0) continue;
    const int32_t got = ja::core::detail::SqrtRaw<32>(a);
    if (!CHECK(got <= want + 1e-9 && want - got <= want * std::ldexp(1.0, -15) + 1.0)) break;
  }
  CHECK_EQ(SaturationCount(), 0u);
  using Accel = ja::core::Fixed<16>;
  using Omega = ja::core::Fixed<24>;
  const Accel big(10.9f), small(0.01f);
  CHECK_NEAR(ja::core::Sqrt<Omega>(big).ToFloat(), std::sqrt(big.ToFloat()), 1e-4);
  CHECK_NEAR(ja::core::Sqrt<Omega>(small).ToFloat(), std::sqrt(small.ToFloat()), 4e-6);
  CHECK_EQ(ja::core::Sqrt<Omega>(Accel(-3.0f)).raw(), 0);
  CHECK_EQ(ja::core::Sqrt<Omega>(Accel(0.0f)).raw(), 0);
  CHECK_NEAR(ja::core::Sqrt<float>(2.0f), std::sqrt(2.0), 1e-6);
  CHECK_EQ(SaturationCount(), 0u);
}

// ReciprocalRaw: 2^k / a low by at most 1.03 2^-18 relative + 1 LSB (seed + one Newton step),
// over normalised mantissas from every segment and every exponent; saturation is counted.
void TestReciprocal() {
  SaturationCount() = 0;
  uint32_t x = 12345u;
  double worst = 0.0;
  for (int i = 0; i < 20000; ++i) {
    x = x * 1664525u + 1013904223u;
    const uint32_t a = (x >> (i % 31)) | 1u;
    const double want = std::ldexp(1.0, 44) / static_cast<double>(a);
    if (want >= 2147483647.0) continue;
    const int32_t got = ja::core::detail::ReciprocalRaw<44>(a);
    const double err = (want - static_cast<double>(got)) / want;
    if (!CHECK(std::fabs(want - got) <= 1.03 * want * std::ldexp(1.0, -18) + 1.0)) break;
    if (err > worst) worst = err;
  }
  CHECK(worst > 0.0);  // the bound is not vacuous: the seed error shows
  CHECK_EQ(SaturationCount(), 0u);
  CHECK_EQ(ja::core::detail::ReciprocalRaw<44>(1u), kMax);  // 2^44 saturates
  CHECK_EQ(SaturationCount(), 1u);
  // Powers of two sit at the seed segment's edge: low by the full Newton error, 2^-18.
  const int32_t r24 = ja::core::detail::ReciprocalRaw<44>(1u << 24);  // 2^20
  CHECK(r24 <= (1 << 20) && r24 >= (1 << 20) - 5);
  CHECK_EQ(ja::core::detail::ReciprocalRaw<44>(0xFFFFFFFFu), 4096);  // 2^44 / (2^32 - 1)
  // Through the policy: 1/0.3 in Q11.20 from Q7.24; a negative operand keeps the sign.
  using Inverse = ja::core::Fixed<20>;
  using Noise = ja::core::Fixed<24>;
  const double third = std::ldexp(1.0, 44) / Noise(0.3f).raw();
  CHECK(std::fabs(ja::core::Recip<Inverse>(Noise(0.3f)).raw() - third) <= 6.0);
  CHECK(std::fabs(ja::core::Recip<Inverse>(Noise(-0.3f)).raw() + third) <= 6.0);
  CHECK_EQ(SaturationCount(), 1u);
  CHECK_EQ(ja::core::Recip<Inverse>(Noise(0.0f)).raw(), kMax);  // 1/0: saturated, counted
  CHECK_EQ(SaturationCount(), 2u);
  SaturationCount() = 0;
}

// 64-bit word shifts (byte moves + single-bit steps) against int64 arithmetic.
void TestWideShifts() {
  uint32_t x = 777u;
  for (int i = 0; i < 5000; ++i) {
    x = x * 1664525u + 1013904223u;
    const uint32_t y = x * 2654435761u;
    const int32_t a = static_cast<int32_t>(x), b = static_cast<int32_t>(y);
    const int64_t p = static_cast<int64_t>(a) * b;
    const ja::core::detail::Wide w = ja::core::detail::MultiplyWide(a, b);
    const ja::core::detail::Wide s18 = ja::core::detail::ShiftRightWide<18>(w);
    const ja::core::detail::Wide s29 = ja::core::detail::ShiftRightWide<29>(w);
    const auto join = [](ja::core::detail::Wide v) {
      return static_cast<int64_t>((static_cast<uint64_t>(static_cast<uint32_t>(v.hi)) << 32) |
                                  v.lo);
    };
    if (!CHECK_EQ(join(s18), p >> 18)) break;
    if (!CHECK_EQ(join(s29), p >> 29)) break;
    if (!CHECK_EQ(join(ja::core::detail::WidenRaw<18>(a)), static_cast<int64_t>(a) * (1 << 18)))
      break;
    if (!CHECK_EQ(join(ja::core::detail::WidenRaw<29>(a)), static_cast<int64_t>(a) * (1 << 29)))
      break;
    ja::core::detail::Wide acc = w;
    ja::core::detail::MacWide(acc, b, a);
    ja::core::detail::MsubWide(acc, a, a);
    if (!CHECK_EQ(join(acc), static_cast<int64_t>(static_cast<uint64_t>(p) * 2u -
                                                  static_cast<uint64_t>(int64_t{a} * a))))
      break;
  }
}

// MacWide32x16 and MsubWide32x16 (numeric_policy.hpp; 8-MUL assembly on AVR in fixed_mac_avr.hpp,
// compared with this x86 build by the AVR filter bench) against an independent uint64 sum:
// acc + a*b modulo 2^64, both signs of the 16-bit operand, accumulators at the carry and borrow
// edges.
void TestMac32x16() {
  using ja::core::detail::Wide;
  const int32_t as[] = {kMax, kMin, 1, -1, 0, 0x40000000, -0x10000};
  const int16_t bs[] = {32767, -32768, 1, -1, 0, 256, -256};
  const uint64_t accs[] = {0u, ~uint64_t{0}, uint64_t{1} << 63, (uint64_t{1} << 63) - 1u,
                           0x00000000FFFFFFFFu};
  uint32_t lcg = 7;
  for (int i = 0; i < 2000; ++i) {
    int32_t a;
    int16_t b;
    if (i < 49) {
      a = as[i % 7];
      b = bs[i / 7];
    } else {
      lcg = lcg * 1664525u + 1013904223u;
      a = static_cast<int32_t>(lcg >> (lcg & 15u));
      lcg = lcg * 1664525u + 1013904223u;
      b = static_cast<int16_t>(lcg >> 16);
    }
    const uint64_t acc0 = accs[i % 5] + static_cast<uint64_t>(i) * 0x0123456789ABull;
    Wide w{static_cast<uint32_t>(acc0), static_cast<int32_t>(static_cast<uint32_t>(acc0 >> 32))};
    ja::core::detail::MacWide32x16(w, a, b);
    const uint64_t want = acc0 + static_cast<uint64_t>(static_cast<int64_t>(a) * b);
    const uint64_t got =
        (static_cast<uint64_t>(static_cast<uint32_t>(w.hi)) << 32) | static_cast<uint64_t>(w.lo);
    if (!CHECK_EQ(got, want)) break;
    ja::core::detail::MsubWide32x16(w, b, static_cast<int16_t>(a));  // acc - b * a16
    const uint64_t want2 =
        want - static_cast<uint64_t>(static_cast<int64_t>(b) * static_cast<int16_t>(a));
    const uint64_t got2 =
        (static_cast<uint64_t>(static_cast<uint32_t>(w.hi)) << 32) | static_cast<uint64_t>(w.lo);
    if (!CHECK_EQ(got2, want2)) break;
  }
}

int main() {
  TestMultiply();
  TestMac32x16();
  TestAccumulator();
  TestAddSubtractNegate();
  TestDivide();
  TestConversions();
  TestTrig();
  TestEigenWithFixed();
  TestReciprocal();
  TestSqrt();
  TestWideShifts();
  return ja_test::Finish("test_fixed_point");
}
