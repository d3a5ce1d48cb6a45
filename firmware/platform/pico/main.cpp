// The Pico image's main for now: no peripherals yet (README.md "What is next"), only the portable
// filter core on the Cortex-M0+. A FixedPolicy joint filter configured on the gravity bench's
// geometry (two 2-sensor arrays, 30 cm links) steps forever on a static pose; the angle goes to
// a volatile so the compiler keeps every step. A debugger (or the emulator of a later session)
// reads g_theta_raw (Q3.28 rad) and g_steps.
#include <stdint.h>

#include "core/joint_filter.hpp"

using ja::core::FixedPolicy;

namespace {

constexpr int kN = 2;  // sensors per link
constexpr float kSamplePeriodS = 0.01f;

ja::core::Settings<FixedPolicy, kN> g_settings;
ja::core::FilterState<FixedPolicy> g_state;
Eigen::Matrix<FixedPolicy::Accel, 2 * kN, 1> g_read_a, g_read_b;

}  // namespace

volatile int32_t g_theta_raw;  // the last step's theta, Q3.28 rad
volatile uint32_t g_steps;     // steps run (0: Configure refused the geometry)

int main() {
  // The gravity bench (firmware/tests/test_joint_filter.cpp): sensors 4.75 and 27.5 cm from the
  // joint, noise variance 4e-4 (m/s^2)^2 per reading.
  const float d1 = 0.0475f, d2 = 0.275f, var = 4.0e-4f;
  const ja::core::ArrayGeometry<kN> geo_a{
      {{0.30f - d1, 0.0f}, {0.30f - d2, 0.0f}}, {0.30f, 0.0f}, {var, var, var, var}};
  const ja::core::ArrayGeometry<kN> geo_b{
      {{d1, 0.0f}, {d2, 0.0f}}, {0.0f, 0.0f}, {var, var, var, var}};
  if (!ja::core::Configure<FixedPolicy, kN>(geo_a, geo_b, kSamplePeriodS, g_settings)) {
    for (;;) {
      __asm volatile("" ::: "memory");
    }
  }
  ja::core::Reset(g_state);
  // At rest, link a level and link b at 90 degrees: gravity along +y in a, along +x in b.
  const auto g = FixedPolicy::Accel::FromRaw(static_cast<int32_t>(9.81f * 65536.0f));
  const auto zero = FixedPolicy::Accel::FromRaw(0);
  for (int i = 0; i < kN; ++i) {
    g_read_a(2 * i) = zero;
    g_read_a(2 * i + 1) = g;
    g_read_b(2 * i) = g;
    g_read_b(2 * i + 1) = zero;
  }
  for (;;) {
    ja::core::Step<FixedPolicy, kN>(g_settings, g_read_a, g_read_b, g_state);
    g_theta_raw = g_state.theta.raw();
    g_steps = g_steps + 1;
  }
}
