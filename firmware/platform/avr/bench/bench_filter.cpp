// The joint filter (firmware/core/joint_filter.hpp) measured on the ATmega2560 in simavr: every
// step of recorded scenario runs through the fixed-point build and the float build of the same
// source, each step in its own cycle region ("filter_fixed", "filter_float"; the harness reports
// the worst step). Inputs arrive byte by byte through the harness (--input, GPIOR1) on AVR and
// from the file named on the command line on x86, in the format written by
// jointangle.bench.parity.write_core_input (little-endian):
//   uint32 n_runs; per run: uint32 n_steps, float dt, float geometry (per link: sensors in use,
//   sensor x, y pairs, joint x, y, noise variance per reading, read delay per sensor), then
//   n_steps x readings int32 Q15.16.
// "check" lines (FNV-1a of every fixed-point state, counters) must be identical on both.
#include <stdint.h>
#include <string.h>

#include "bench_io.hpp"
// -DJA_BENCH_STEP_PROFILE: every section of Step becomes a region of its own (20.. fixed, 30..
// float; "filter_fixed"/"filter_float" then time only the part before the time update).
#if defined(JA_BENCH_STEP_PROFILE)
#define JA_STEP_PROFILE(id) (bench::End(), bench::Begin(static_cast<uint8_t>(id)))
#endif
#include "core/joint_filter.hpp"

#if defined(__AVR__)
#include <avr/io.h>
namespace {
uint8_t ReadByte() { return GPIOR1; }
void OpenInput(int, char**) {}
}  // namespace
#elif defined(__arm__)
namespace {
uint8_t ReadByte() { return ja::pico::ReadInputByte(); }
void OpenInput(int, char**) {}
}  // namespace
#else
#include <cstdio>
namespace {
std::FILE* g_input = nullptr;
uint8_t ReadByte() {
  const int c = g_input ? std::fgetc(g_input) : EOF;
  return c == EOF ? 0 : static_cast<uint8_t>(c);
}
void OpenInput(int argc, char** argv) {
  if (argc > 1) g_input = std::fopen(argv[1], "rb");
  if (!g_input) {
    std::fputs("bench_filter: usage: bench_filter_native INPUT.bin\n", stderr);
    std::exit(2);
  }
}
}  // namespace
#endif

namespace {

using ja::core::FixedPolicy;
using ja::core::FloatPolicy;
// The app's filter: Settings for up to kMaxSensorsPerLink sensors per link, the count per link a
// configuration value (each run's geometry says it). Steps are timed per sensor count: the
// largest of the two links' counts picks the region (2: filter_fixed / filter_float).
constexpr int kN = ja::core::kMaxSensorsPerLink;
enum Region : uint8_t {
  kEmpty = 1,
  kFilterFixed,
  kFilterFloat,
  kFilterFixed3,
  kFilterFloat3,
  kFilterFixed4,
  kFilterFloat4,
  kFilterFixedRelease,  // the one step per filter start that releases the omega^2 rows
  kFilterFloatRelease
};

uint32_t ReadU32() {
  uint32_t v = 0;
  for (uint8_t i = 0; i < 4; ++i) v |= static_cast<uint32_t>(ReadByte()) << (8 * i);
  return v;
}
float ReadFloat() {
  const uint32_t u = ReadU32();
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

/// One link's geometry: sensors in use, x, y per slot, joint x, y, noise variance per reading,
/// read delay per slot (the host's jointangle.estimators.mirror._geometry layout).
void ReadGeometry(ja::core::ArrayGeometry<kN>& g) {
  const float count = ReadFloat();
  g.count = count >= 0.0f && count <= static_cast<float>(kN) ? static_cast<uint8_t>(count) : 0;
  for (int i = 0; i < kN; ++i) {
    g.sensor_m[i][0] = ReadFloat();
    g.sensor_m[i][1] = ReadFloat();
  }
  g.joint_m[0] = ReadFloat();
  g.joint_m[1] = ReadFloat();
  for (int j = 0; j < 2 * kN; ++j) g.noise_var[j] = ReadFloat();
  for (int i = 0; i < kN; ++i) g.read_delay_s[i] = ReadFloat();
}

uint32_t Fnv(uint32_t h, int32_t v) {
  for (uint8_t i = 0; i < 4; ++i) {
    h ^= static_cast<uint8_t>(static_cast<uint32_t>(v) >> (8 * i));
    h *= 16777619u;
  }
  return h;
}

void PrintCheck(const char* name, int32_t v) {
  bench::Print("check ");
  bench::Print(name);
  bench::Print(" ");
  bench::PrintInt(v);
  bench::Print("\n");
}

// Rounding self-check: products rounded by every shift k = 9..31 (RoundShiftSaturate, which is
// assembly on AVR: core/fixed_round_avr.hpp) over random operands of all magnitudes and the
// extremes, so both the in-range and the saturating paths are compared with x86.
template <int K>
struct RoundingCheck {
  static constexpr int kFa = K == 9 ? 8 : 16;
  static constexpr int kFr = kFa + 24 - K;
  static uint32_t Run(uint32_t h, uint32_t& state) {
    static const int32_t kEdges[] = {0x7FFFFFFF, -0x7FFFFFFF - 1, 1, -1, 0, 0x40000000};
    for (uint8_t i = 0; i < 120; ++i) {
      int32_t a, b;
      if (i < 36) {
        a = kEdges[i % 6];
        b = kEdges[i / 6];
      } else {
        state = state * 1664525u + 1013904223u;
        const uint32_t x = state;
        state = state * 1664525u + 1013904223u;
        a = static_cast<int32_t>(x) >> (x & 31u);
        b = static_cast<int32_t>(state) >> ((state >> 8) & 31u);
      }
      const auto r = ja::core::Mul<ja::core::Fixed<kFr>>(ja::core::Fixed<kFa>::FromRaw(a),
                                                         ja::core::Fixed<24>::FromRaw(b));
      h = Fnv(h, r.raw());
    }
    return RoundingCheck<K + 1>::Run(h, state);
  }
};
template <>
struct RoundingCheck<32> {
  static uint32_t Run(uint32_t h, uint32_t&) { return h; }
};

// The 32x16 product (assembly on AVR: core/fixed_point.hpp MultiplyWide32x16) over the extremes
// and random operands of every magnitude: hashed, compared with x86.
uint32_t Product32x16Check(uint32_t h, uint32_t& state) {
  static const int32_t kA[] = {0x7FFFFFFF, -0x7FFFFFFF - 1, 1, -1, 0, 0x40000000};
  static const uint16_t kB[] = {0xFFFFu, 0x8000u, 1u, 0u, 0x7FFFu, 0x0100u};
  for (uint8_t i = 0; i < 160; ++i) {
    int32_t a;
    uint16_t b;
    if (i < 36) {
      a = kA[i % 6];
      b = kB[i / 6];
    } else {
      state = state * 1664525u + 1013904223u;
      a = static_cast<int32_t>(state) >> (state & 31u);
      state = state * 1664525u + 1013904223u;
      b = static_cast<uint16_t>(state >> 16);
    }
    const ja::core::detail::Wide w = ja::core::detail::MultiplyWide32x16(a, b);
    h = Fnv(Fnv(h, static_cast<int32_t>(w.lo)), w.hi);
  }
  return h;
}

// The 32x16 multiply-accumulate and -subtract (assembly on AVR: core/fixed_mac_avr.hpp
// MacWide32x16Asm, MsubWide32x16Asm), signed 16-bit operand: chains of 4 (MAC, MSUB, MAC, MSUB)
// from accumulators near every carry and borrow edge (0, -1 = all ones, 2^63 - 1, -2^63, random)
// over the extreme and random operands of every magnitude and both signs: hashed, compared with x86
// (the int64 products added).
uint32_t Mac32x16Check(uint32_t h, uint32_t& state) {
  static const int32_t kA[] = {0x7FFFFFFF, -0x7FFFFFFF - 1, 1, -1, 0, 0x40000000, -0x00010000};
  static const int16_t kB[] = {0x7FFF, -0x7FFF - 1, 1, -1, 0, 0x0100, -0x0100};
  static const uint32_t kAccLo[] = {0u, 0xFFFFFFFFu, 0xFFFFFFFFu, 0u, 0xFFFF0000u};
  static const int32_t kAccHi[] = {0, -1, 0x7FFFFFFF, -0x7FFFFFFF - 1, 0x7FFFFFFF};
  for (uint8_t i = 0; i < 200; ++i) {
    ja::core::detail::Wide acc;
    if (i % 6 < 5) {
      acc = ja::core::detail::Wide{kAccLo[i % 6], kAccHi[i % 6]};
    } else {
      state = state * 1664525u + 1013904223u;
      const uint32_t x = state;
      state = state * 1664525u + 1013904223u;
      acc = ja::core::detail::Wide{x, static_cast<int32_t>(state)};
    }
    for (uint8_t j = 0; j < 4; ++j) {
      int32_t a;
      int16_t b;
      if (i < 49 && j == 0) {
        a = kA[i % 7];
        b = kB[i / 7];
      } else {
        state = state * 1664525u + 1013904223u;
        a = static_cast<int32_t>(state) >> (state & 31u);
        state = state * 1664525u + 1013904223u;
        b = static_cast<int16_t>(static_cast<int32_t>(state) >> (16 + ((state >> 4) & 15u)));
      }
      if (j % 2 == 0) {
        ja::core::detail::MacWide32x16(acc, a, b);
      } else {
        ja::core::detail::MsubWide32x16(acc, a, b);
      }
      h = Fnv(Fnv(h, static_cast<int32_t>(acc.lo)), acc.hi);
    }
  }
  return h;
}

// The 32x32 multiply-accumulate that skips b's top byte when b fits 24 bits (assembly on AVR:
// core/fixed_mac_avr.hpp MacWideB24Asm, the link rows' kernel) over b at and around the 24-bit
// edges (+-2^23, +-2^23 - 1, 0, -1) and of every magnitude, a of every magnitude and sign, from
// accumulators at the carry and borrow edges: hashed, compared with x86 (the int64 products).
uint32_t MacB24Check(uint32_t h, uint32_t& state) {
  static const int32_t kB[] = {0x7FFFFF, -0x800000, 0x800000, -0x800001, 0, -1, 1, 0x7FFFFFFF};
  static const uint32_t kAccLo[] = {0u, 0xFFFFFFFFu, 0xFFFFFFFFu, 0u};
  static const int32_t kAccHi[] = {0, -1, 0x7FFFFFFF, -0x7FFFFFFF - 1};
  for (uint16_t i = 0; i < 240; ++i) {
    ja::core::detail::Wide acc{kAccLo[i % 4], kAccHi[i % 4]};
    for (uint8_t j = 0; j < 3; ++j) {
      state = state * 1664525u + 1013904223u;
      const int32_t a = static_cast<int32_t>(state) >> (state & 31u);
      state = state * 1664525u + 1013904223u;
      const int32_t b =
          (i < 64 && j == 0) ? kB[i % 8] : static_cast<int32_t>(state) >> (state & 31u);
      ja::core::detail::MacWideB24(acc, a, b);
      h = Fnv(Fnv(h, static_cast<int32_t>(acc.lo)), acc.hi);
    }
  }
  return h;
}

// The 16-bit operand type (core/numeric_policy.hpp Fixed16: the Row format) through every
// operation the filter uses it in — casts from Q15.16 and Q7.24, sums of 32x16 products with
// the 16-bit operand first or second, a Fixed16 sum with an offset, a product rounded to 16
// bits, the negation — over random operands of every magnitude, saturating cases included:
// hashed, compared with x86 (an int16 bound written as -0x8000 is unsigned on AVR: every
// Fixed16 result saturated there once).
uint32_t Fixed16Check(uint32_t h, uint32_t& state) {
  using ja::core::Fixed;
  using Row = ja::core::Fixed16<9>;
  for (uint8_t which = 0; which < 7; ++which) {
    for (uint8_t i = 0; i < 100; ++i) {
      state = state * 1664525u + 1013904223u;
      const int32_t a = static_cast<int32_t>(state) >> (state & 31u);
      state = state * 1664525u + 1013904223u;
      const int32_t b = static_cast<int32_t>(state) >> (state & 31u);
      state = state * 1664525u + 1013904223u;
      const Row c = Row::FromRaw(
          static_cast<int16_t>(static_cast<int32_t>(state) >> (16 + ((state >> 4) & 15u))));
      int32_t r = 0;
      if (which == 0) r = ja::core::Cast<Row>(Fixed<16>::FromRaw(a)).raw();
      if (which == 1) r = ja::core::Cast<Row>(Fixed<24>::FromRaw(a)).raw();
      if (which == 2) {
        ja::core::Sum<Fixed<24>, Fixed<30>, Row> s;
        s.Add(Fixed<30>::FromRaw(a), c);
        s.Add(Fixed<30>::FromRaw(b), c);
        r = s.Result().raw();
      }
      if (which == 3) {
        ja::core::Sum<Fixed<24>, Row, Fixed<24>> s;
        s.Add(c, Fixed<24>::FromRaw(a));
        s.Subtract(c, Fixed<24>::FromRaw(b));
        r = s.Result().raw();
      }
      if (which == 4) {
        ja::core::Sum<Row, Fixed<24>, Row> s;
        s.AddValue(c);
        s.Subtract(Fixed<24>::FromRaw(a >> 8), c);
        r = s.Result().raw();
      }
      if (which == 5) r = ja::core::Mul<Row>(Fixed<24>::FromRaw(a >> 8), c).raw();
      if (which == 6) r = (-c).raw();
      h = Fnv(h, r);
    }
  }
  return h;
}

// Static storage: direct addressing on AVR, and the frame stays small (NUMERICS.md).
ja::core::Settings<FixedPolicy, kN> g_fixed_settings;
ja::core::Settings<FloatPolicy, kN> g_float_settings;
ja::core::FilterState<FixedPolicy> g_fixed;
ja::core::FilterState<FloatPolicy> g_float;
Eigen::Matrix<FixedPolicy::Accel, 2 * kN, 1> g_qa, g_qb;
Eigen::Matrix<float, 2 * kN, 1> g_fa, g_fb;

}  // namespace

int main(int argc, char** argv) {
  OpenInput(argc, argv);
  bench::Name(kEmpty, "empty");
  bench::Name(kFilterFixed, "filter_fixed");
  bench::Name(kFilterFloat, "filter_float");
  bench::Name(kFilterFixed3, "filter_fixed_n3");
  bench::Name(kFilterFloat3, "filter_float_n3");
  bench::Name(kFilterFixed4, "filter_fixed_n4");
  bench::Name(kFilterFloat4, "filter_float_n4");
  bench::Name(kFilterFixedRelease, "filter_fixed_release");
  bench::Name(kFilterFloatRelease, "filter_float_release");
#if defined(JA_BENCH_STEP_PROFILE)
  // Step's sections (joint_filter.hpp JA_STEP_MARK 20..25, float 30..35); filter_fixed and
  // filter_float then time the link rows and the start-up only.
  static const char* const kFixedNames[] = {"fixed_time_update",  "fixed_measurement",
                                            "fixed_noise_blocks", "fixed_decorrelation",
                                            "fixed_updates",      "fixed_wrap_health"};
  static const char* const kFloatNames[] = {"float_time_update",  "float_measurement",
                                            "float_noise_blocks", "float_decorrelation",
                                            "float_updates",      "float_wrap_health"};
  for (uint8_t i = 0; i < 6; ++i) {
    bench::Name(static_cast<uint8_t>(20 + i), kFixedNames[i]);
    bench::Name(static_cast<uint8_t>(30 + i), kFloatNames[i]);
  }
#endif
  bench::Begin(kEmpty);
  bench::End();
  {
    ja::core::SaturationCount() = 0;
    uint32_t state = 1u;
    PrintCheck("rounding_hash", static_cast<int32_t>(RoundingCheck<9>::Run(2166136261u, state)));
    PrintCheck("rounding_saturations", ja::core::SaturationCount());
    PrintCheck("product32x16_hash", static_cast<int32_t>(Product32x16Check(2166136261u, state)));
    PrintCheck("mac32x16_hash", static_cast<int32_t>(Mac32x16Check(2166136261u, state)));
    PrintCheck("mac_b24_hash", static_cast<int32_t>(MacB24Check(2166136261u, state)));
    ja::core::SaturationCount() = 0;
    PrintCheck("fixed16_hash", static_cast<int32_t>(Fixed16Check(2166136261u, state)));
    PrintCheck("fixed16_saturations", ja::core::SaturationCount());
    ja::core::SaturationCount() = 0;
  }
  const uint32_t n_runs = ReadU32();
  uint32_t hash = 2166136261u;
  int32_t worst_theta_diff_raw = 0;  // |theta fixed - theta float| in Q28 raw, for information
  for (uint32_t run = 0; run < n_runs; ++run) {
    const uint32_t n_steps = ReadU32();
    const float dt = ReadFloat();
    ja::core::ArrayGeometry<kN> ga, gb;
    ReadGeometry(ga);
    ReadGeometry(gb);
    const bool ok_fixed = ja::core::Configure<FixedPolicy, kN>(ga, gb, dt, g_fixed_settings);
    const bool ok_float = ja::core::Configure<FloatPolicy, kN>(ga, gb, dt, g_float_settings);
    PrintCheck("configured", (ok_fixed ? 1 : 0) + (ok_float ? 2 : 0));
    const uint8_t n_max = ga.count > gb.count ? ga.count : gb.count;
    const uint8_t fixed_region = n_max >= 4   ? kFilterFixed4
                                 : n_max == 3 ? kFilterFixed3
                                              : kFilterFixed;
    const uint8_t float_region = n_max >= 4   ? kFilterFloat4
                                 : n_max == 3 ? kFilterFloat3
                                              : kFilterFloat;
    ja::core::Reset(g_fixed);
    ja::core::Reset(g_float);
    for (uint32_t k = 0; k < n_steps; ++k) {
      for (int j = 0; j < 4 * kN; ++j) {
        const int32_t raw = static_cast<int32_t>(ReadU32());
        const FixedPolicy::Accel q = FixedPolicy::Accel::FromRaw(raw);
        const float f = static_cast<float>(raw) * (1.0f / 65536.0f);
        if (j < 2 * kN) {
          g_qa(j) = q;
          g_fa(j) = f;
        } else {
          g_qb(j - 2 * kN) = q;
          g_fb(j - 2 * kN) = f;
        }
      }
      // The step that gives the omega^2 rows their first update (ReleaseSum, once
      // per filter start) is timed apart: the loop's budget is set by the others.
      const bool release = g_fixed.initialised && !g_fixed.omega2_rows_on &&
                           g_fixed.health.steps >= g_fixed_settings.hold_steps;
      bench::Begin(release ? static_cast<uint8_t>(kFilterFixedRelease) : fixed_region);
      ja::core::Step<FixedPolicy, kN>(g_fixed_settings, g_qa, g_qb, g_fixed);
      bench::End();
      bench::Begin(release ? static_cast<uint8_t>(kFilterFloatRelease) : float_region);
      ja::core::Step<FloatPolicy, kN>(g_float_settings, g_fa, g_fb, g_float);
      bench::End();
      hash = Fnv(hash, g_fixed.omega(0).raw());
      hash = Fnv(hash, g_fixed.omega(1).raw());
      hash = Fnv(hash, g_fixed.theta.raw());
      hash = Fnv(hash, ja::core::AnalyticalAngleOf(g_fixed).raw());
      const ja::core::FixedPolicy::Angle as_fixed(g_float.theta);
      int32_t d = as_fixed.raw() - g_fixed.theta.raw();
      if (d < 0) d = -d;
      if (d > worst_theta_diff_raw && k * dt >= 2.0f) worst_theta_diff_raw = d;
    }
    PrintCheck("saturations", g_fixed.health.saturations);
    PrintCheck("skipped", g_fixed.health.skipped_updates);
    PrintCheck("theta_final", g_fixed.theta.raw());
  }
  PrintCheck("state_hash", static_cast<int32_t>(hash));
  bench::Print("value fixed_vs_float_dtheta_q28 ");
  bench::PrintInt(worst_theta_diff_raw);
  bench::Print("\n");
  bench::Finish();
}
