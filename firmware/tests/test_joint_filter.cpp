// The joint filter on x86 (sanitizers on): configuration from geometry, start-up from the
// analytical estimate, convergence on a static pose, fixed point vs the float build of the same
// source, symmetric P, health counters, Reset, and the RAM it needs.
#include <cmath>
#include <cstdio>

#include "check.hpp"
#include "core/joint_filter.hpp"

namespace {

using ja::core::ArrayGeometry;
using ja::core::FixedPolicy;
using ja::core::FloatPolicy;

// The gravity bench: sensors 4.75 and 27.5 cm from the joint on 30 cm links.
void BenchGeometry(ArrayGeometry<2>& a, ArrayGeometry<2>& b, float var = 4.0e-4f) {
  const float d1 = 0.0475f, d2 = 0.275f;
  a = ArrayGeometry<2>{
      {{0.30f - d1, 0.0f}, {0.30f - d2, 0.0f}}, {0.30f, 0.0f}, {var, var, var, var}};
  b = ArrayGeometry<2>{{{d1, 0.0f}, {d2, 0.0f}}, {0.0f, 0.0f}, {var, var, var, var}};
}

// Static pose: gravity g_a in link a's frame, the same vector seen from b: v^b = R(theta)^T v^a.
template <class P>
void StaticReadings(float theta, Eigen::Matrix<typename P::Accel, 4, 1>& a,
                    Eigen::Matrix<typename P::Accel, 4, 1>& b) {
  const float gx = 0.0f, gy = 9.80665f;
  const float c = std::cos(theta), s = std::sin(theta);
  const float bx = c * gx - s * gy, by = s * gx + c * gy;  // R(theta)^T g
  for (int i = 0; i < 2; ++i) {
    a(2 * i) = typename P::Accel(gx);
    a(2 * i + 1) = typename P::Accel(gy);
    b(2 * i) = typename P::Accel(bx);
    b(2 * i + 1) = typename P::Accel(by);
  }
}

template <class P>
float RunStatic(float theta, int steps, ja::core::FilterState<P>& st) {
  ArrayGeometry<2> ga, gb;
  BenchGeometry(ga, gb);
  ja::core::Settings<P, 2> s;
  CHECK((ja::core::Configure<P, 2>(ga, gb, 0.002f, s)));
  CHECK_EQ(s.hold_steps, 125);
  ja::core::Reset(st);
  Eigen::Matrix<typename P::Accel, 4, 1> a, b;
  StaticReadings<P>(theta, a, b);
  ja::core::Step<P, 2>(s, a, b, st);
  // Initialised from eq. 12 at once.
  CHECK_NEAR(ja::core::ToFloat(st.theta), theta, 2e-3);
  CHECK_NEAR(ja::core::ToFloat(ja::core::AnalyticalAngleOf(st)), theta, 2e-4);
  for (int k = 1; k < steps; ++k) ja::core::Step<P, 2>(s, a, b, st);
  for (int i = 0; i < 3; ++i) {
    CHECK(ja::core::ToFloat(st.p(i, i)) > 0.0f);
    for (int j = 0; j < 3; ++j) CHECK(st.p(i, j) == st.p(j, i));
  }
  CHECK_EQ(st.health.steps, static_cast<uint32_t>(steps));
  CHECK_EQ(st.health.skipped_updates, 0);
  return ja::core::ToFloat(st.theta);
}

// Q^ of one reading: (density g)^2 fs / 2 + lsb^2 / 12 (docs/design.md §3, as the host).
float ReadingVariance(float density_ug, float lsb_mps2, float rate_hz) {
  const float sigma = density_ug * 1e-6f * 9.80665f;
  return sigma * sigma * rate_hz / 2.0f + lsb_mps2 * lsb_mps2 / 12.0f;
}

// Every supported sensor at 100..1000 Hz: no quantity leaves its Q format (FILTER.md, Q table).
// ADXL357 at 100 Hz (Q^ = 3.1e-5) makes D ~ 6e-5 and 1/D ~ 1.6e4, past the former Q11.20 1/D.
void CheckNoSaturation() {
  struct Sensor {
    const char* name;
    float density_ug, lsb_mps2;
  };
  const Sensor sensors[] = {{"adxl345", 290.0f, 0.0039f * 9.80665f},
                            {"adxl357", 80.0f, 9.80665f / 51200.0f},
                            {"bno055", 150.0f, 0.01f}};
  for (const Sensor& sensor : sensors) {
    for (float rate : {100.0f, 500.0f, 1000.0f}) {
      ArrayGeometry<2> ga, gb;
      BenchGeometry(ga, gb, ReadingVariance(sensor.density_ug, sensor.lsb_mps2, rate));
      ja::core::Settings<FixedPolicy, 2> s;
      CHECK((ja::core::Configure<FixedPolicy, 2>(ga, gb, 1.0f / rate, s)));
      ja::core::FilterState<FixedPolicy> st;
      ja::core::Reset(st);
      Eigen::Matrix<FixedPolicy::Accel, 4, 1> a, b;
      const float theta = -0.8f;
      StaticReadings<FixedPolicy>(theta, a, b);
      // At rest P22 shrinks until the theta rows' s ~ D: the smallest s, the largest 1/s.
      const int steps = static_cast<int>(rate * 2.0f);
      for (int k = 0; k < steps; ++k) ja::core::Step<FixedPolicy, 2>(s, a, b, st);
      if (st.health.saturations != 0) {
        std::fprintf(stderr, "%s at %g Hz: %u saturations\n", sensor.name,
                     static_cast<double>(rate), static_cast<unsigned>(st.health.saturations));
      }
      CHECK_EQ(st.health.saturations, 0);
      CHECK_EQ(st.health.skipped_updates, 0);
      CHECK_NEAR(ja::core::ToFloat(st.theta), theta, 2e-3);
    }
  }
}

}  // namespace

bool Same(float x, float y) { return x == y; }
template <int F>
bool Same(ja::core::Fixed<F> x, ja::core::Fixed<F> y) {
  return x.raw() == y.raw();
}
float LagValue(float v) { return v; }
template <int F>
float LagValue(ja::core::Fixed16<F> v) {
  return v.ToFloat();
}

// Step 0 (AlignReadings): sensor i sampled tau_i after the row's time, readings on a ramp
// a(t) = a0 + s t are turned to a(t_k + tau_m), tau_m their mean, exactly (to the fixed point's
// rounding); not on the filter's first step, nor over missed periods; a rig sampled all at once
// is left alone, and a common latency goes to the output (OutputAngle) alone.
template <class P>
void CheckReadingsTurnedToTheRowTime(float tolerance) {
  using Vec = Eigen::Matrix<typename P::Accel, 4, 1>;
  ArrayGeometry<2> ga, gb;
  BenchGeometry(ga, gb);
  const float dt = 0.004f;
  const float tau[4] = {0.0f, 0.286e-3f, 0.572e-3f, 0.858e-3f};  // links a then b
  ga.read_delay_s[0] = tau[0];
  ga.read_delay_s[1] = tau[1];
  gb.read_delay_s[0] = tau[2];
  gb.read_delay_s[1] = tau[3];
  ja::core::Settings<P, 2> s;
  CHECK((ja::core::Configure<P, 2>(ga, gb, dt, s)));
  const float tau_m = (tau[0] + tau[1] + tau[2] + tau[3]) / 4.0f;
  CHECK_EQ(s.read_lag_mask[0], 0x0F);  // every sensor off the mean
  CHECK_EQ(s.read_lag_mask[1], 0x0F);
  CHECK_NEAR(LagValue(s.read_lag[1][3]), (tau[3] - tau_m) / dt, 1e-4);
  CHECK_NEAR(LagValue(s.read_lag[0][0]), (tau[0] - tau_m) / dt, 1e-4);
  CHECK_NEAR(ja::core::ToFloat(s.output_lead), -tau_m, 1e-8);
  const float slope[4] = {3.0f, -2.0f, 5.0f, 1.5f};  // m/s^3 per reading of a sensor
  const auto ramp = [&](int k, bool skewed, Vec& a, Vec& b) {
    for (int j = 0; j < 4; ++j) {
      const float t = dt * static_cast<float>(k);
      a(j) = typename P::Accel(1.0f + slope[j] * (t + (skewed ? tau[j / 2] : tau_m)));
      b(j) = typename P::Accel(9.0f + slope[j] * (t + (skewed ? tau[2 + j / 2] : tau_m)));
    }
  };
  Vec a, b, row_a, row_b, out;
  ja::core::FilterState<P> st;
  ja::core::Reset(st);
  ramp(0, true, a, b);
  ja::core::Step<P, 2>(s, a, b, st);  // first step: as read, kept
  CHECK(Same(st.previous[1][3], b(3)));
  for (int k = 1; k < 4; ++k) {
    ramp(k, true, a, b);
    ramp(k, false, row_a, row_b);
    Vec prev_b;
    for (int j = 0; j < 4; ++j) prev_b(j) = st.previous[1][j];
    ja::core::detail::AlignReadings<P, 2>(s.read_lag[1], s.read_lag_mask[1], true, b,
                                          st.previous[1], out);
    for (int j = 0; j < 4; ++j) {
      CHECK_NEAR(ja::core::ToFloat(out(j)), ja::core::ToFloat(row_b(j)), tolerance);
      CHECK(Same(st.previous[1][j], b(j)));
    }
    for (int j = 0; j < 4; ++j) st.previous[1][j] = prev_b(j);  // as Step found it
    ja::core::Step<P, 2>(s, a, b, st);
  }
  // Over missed periods: the readings as read (held), and kept.
  ja::core::detail::AlignReadings<P, 2>(s.read_lag[0], s.read_lag_mask[0], false, a, st.previous[0],
                                        out);
  for (int j = 0; j < 4; ++j) CHECK(Same(out(j), a(j)));
  // Read all at once: step 0 skipped, the output as the state.
  ga.read_delay_s[0] = ga.read_delay_s[1] = gb.read_delay_s[0] = gb.read_delay_s[1] = 0.0f;
  CHECK((ja::core::Configure<P, 2>(ga, gb, dt, s)));
  CHECK_EQ(s.read_lag_mask[0] | s.read_lag_mask[1], 0);
  CHECK(ja::core::ToFloat(s.output_lead) == 0.0f);
  CHECK(Same(ja::core::OutputAngle(s, st), st.theta));
  // All sampled 2.5 ms before the row (a common latency): step 0 skipped, theta turned forward,
  // theta(t_k) = theta + 2.5 ms (w_a - w_b), wrapped.
  ga.read_delay_s[0] = ga.read_delay_s[1] = gb.read_delay_s[0] = gb.read_delay_s[1] = -2.5e-3f;
  CHECK((ja::core::Configure<P, 2>(ga, gb, dt, s)));
  CHECK_EQ(s.read_lag_mask[0] | s.read_lag_mask[1], 0);
  st.theta = typename P::Angle(3.1f);
  st.omega(0) = typename P::Omega(20.0f);
  st.omega(1) = typename P::Omega(-4.0f);
  CHECK_NEAR(ja::core::ToFloat(ja::core::OutputAngle(s, st)), 3.1f + 0.06f - 6.2831853f, 1e-5);
  st.omega(0) = typename P::Omega(2.0f);
  CHECK_NEAR(ja::core::ToFloat(ja::core::OutputAngle(s, st)), 3.115f, 1e-5);  // no wrap
  st.theta = typename P::Angle(0.5f);
  CHECK_NEAR(ja::core::ToFloat(ja::core::OutputAngle(s, st)), 0.515f, 1e-5);
}

int main() {
  CheckNoSaturation();
  CheckReadingsTurnedToTheRowTime<FloatPolicy>(1e-5f);
  CheckReadingsTurnedToTheRowTime<FixedPolicy>(1e-4f);
  // Geometry checks.
  {
    ArrayGeometry<2> ga, gb;
    BenchGeometry(ga, gb);
    ja::core::Settings<FixedPolicy, 2> s;
    CHECK((ja::core::Configure<FixedPolicy, 2>(ga, gb, 0.01f, s)));
    // G_w2 of link b: [-dx_i, -dy_i] / spread^2, dx = -(d2 - d1)/2 for the first sensor.
    const float spread2 = 2.0f * 0.11375f * 0.11375f;
    CHECK_NEAR(s.b.g_omega2(0, 0).ToFloat(), 0.11375f / spread2, 1e-5);
    CHECK_NEAR(s.b.f(0, 0).ToFloat(), 1.2088f, 1e-3);  // joint outside the array: F > 1
    CHECK(!(ja::core::Configure<FixedPolicy, 2>(ga, gb, 0.0f, s)));  // no sample period
    ArrayGeometry<2> degenerate = ga;
    degenerate.sensor_m[1][0] = degenerate.sensor_m[0][0];
    CHECK(!(ja::core::Configure<FixedPolicy, 2>(degenerate, gb, 0.01f, s)));
    ArrayGeometry<2> narrow = ga;  // 5 mm array: |G| = 200 does not fit Q7.24
    narrow.sensor_m[1][0] = narrow.sensor_m[0][0] + 0.005f;
    CHECK(!(ja::core::Configure<FixedPolicy, 2>(narrow, gb, 0.01f, s)));
    ja::core::Settings<FloatPolicy, 2> sf;
    CHECK((ja::core::Configure<FloatPolicy, 2>(narrow, gb, 0.01f, sf)));  // float has the range
  }
  // Static poses: both builds converge to the pose and agree.
  for (float theta : {0.7f, -2.5f, 3.0f}) {
    ja::core::FilterState<FixedPolicy> fixed;
    ja::core::FilterState<FloatPolicy> flt;
    const float tf = RunStatic<FixedPolicy>(theta, 1000, fixed);
    const float tl = RunStatic<FloatPolicy>(theta, 1000, flt);
    CHECK_NEAR(tf, theta, 1e-3);
    CHECK_NEAR(tl, theta, 1e-3);
    CHECK_NEAR(tf, tl, 2e-4);
    CHECK_NEAR(fixed.omega(0).ToFloat(), 0.0f, 1e-2);
    CHECK_EQ(fixed.health.saturations, 0);
    // theta is pinned; w_a + w_b is not observable at rest (H = 2w = 0), so only P22 shrinks.
    CHECK(fixed.p(2, 2).ToFloat() < 1e-4f);
    CHECK(ja::core::CovarianceTrace(fixed).ToFloat() > 0.0f);
  }
  // No joint acceleration: eq. 12 is not trusted, theta starts at 0 with P = I.
  {
    ArrayGeometry<2> ga, gb;
    BenchGeometry(ga, gb);
    ja::core::Settings<FixedPolicy, 2> s;
    CHECK((ja::core::Configure<FixedPolicy, 2>(ga, gb, 0.01f, s)));
    ja::core::FilterState<FixedPolicy> st;
    ja::core::Reset(st);
    Eigen::Matrix<FixedPolicy::Accel, 4, 1> zero;
    zero.setConstant(FixedPolicy::Accel(0));
    ja::core::Step<FixedPolicy, 2>(s, zero, zero, st);
    CHECK(st.initialised);
    CHECK_EQ(st.theta.raw(), 0);
    CHECK(st.p(2, 2).ToFloat() > 0.99f);
    ja::core::Reset(st);
    CHECK(!st.initialised);
    CHECK_EQ(st.health.steps, 0u);
  }
  // Missed periods (Step's `periods`): the time update runs once per period with the step's
  // readings, then the one measurement update; clamped to 1..kMaxStepPeriods; the first step
  // (initialisation) takes 1.
  {
    using St = ja::core::FilterState<FixedPolicy>;
    ArrayGeometry<2> ga, gb;
    BenchGeometry(ga, gb);
    ja::core::Settings<FixedPolicy, 2> s;
    CHECK((ja::core::Configure<FixedPolicy, 2>(ga, gb, 0.002f, s)));
    Eigen::Matrix<FixedPolicy::Accel, 4, 1> a, b;
    StaticReadings<FixedPolicy>(0.7f, a, b);
    a(0) = FixedPolicy::Accel(1.5f);  // a joint acceleration: omega moves in the time update
    const auto same = [](const St& x, const St& y) {
      bool eq = x.theta.raw() == y.theta.raw() && x.omega(0).raw() == y.omega(0).raw() &&
                x.omega(1).raw() == y.omega(1).raw();
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) eq = eq && x.p(i, j).raw() == y.p(i, j).raw();
      }
      return eq;
    };
    St first3, first1;
    ja::core::Reset(first3);
    ja::core::Reset(first1);
    ja::core::Step<FixedPolicy, 2>(s, a, b, first3, 3);
    ja::core::Step<FixedPolicy, 2>(s, a, b, first1, 1);
    CHECK(same(first3, first1));  // the initialising step ignores periods
    St three = first1, by_hand = first1, one = first1, many = first1, capped = first1;
    St zero = first1;
    ja::core::Step<FixedPolicy, 2>(s, a, b, three, 3);
    // The missed periods hold the previous readings' alpha (half increments in the state).
    const FixedPolicy::Omega h_a = by_hand.half_dw[0], h_b = by_hand.half_dw[1];
    ja::core::detail::TimeUpdate(s, h_a, h_b, h_a, h_b, by_hand);
    ja::core::detail::TimeUpdate(s, h_a, h_b, h_a, h_b, by_hand);
    ja::core::Step<FixedPolicy, 2>(s, a, b, by_hand, 1);
    CHECK(same(three, by_hand));
    ja::core::Step<FixedPolicy, 2>(s, a, b, one, 1);
    CHECK(!same(three, one));  // the missed periods changed the estimate
    ja::core::Step<FixedPolicy, 2>(s, a, b, many, 200);
    ja::core::Step<FixedPolicy, 2>(s, a, b, capped, ja::core::kMaxStepPeriods);
    CHECK(same(many, capped));
    ja::core::Step<FixedPolicy, 2>(s, a, b, zero, 0);
    CHECK(same(zero, one));
  }
  // The time update integrates a linearly varying alpha exactly (float build): from w, theta
  // and half increments h0 = dt alpha0 / 2, h1 = dt alpha1 / 2 of each link, after one period
  //   w' = w + h0 + h1,  theta' = theta + dt dw + dt^2 (2 dalpha0 + dalpha1) / 6.
  {
    using FP = ja::core::FloatPolicy;
    ArrayGeometry<2> ga, gb;
    BenchGeometry(ga, gb);
    ja::core::Settings<FP, 2> s;
    const float dt = 0.01f;
    CHECK((ja::core::Configure<FP, 2>(ga, gb, dt, s)));
    ja::core::FilterState<FP> st;
    ja::core::Reset(st);
    st.omega << 0.3f, -0.2f;
    st.theta = 0.1f;
    const float alpha0_a = 2.0f, alpha1_a = 5.0f, alpha0_b = -1.0f, alpha1_b = 3.0f;  // rad/s^2
    ja::core::detail::TimeUpdate(s, 0.5f * dt * alpha0_a, 0.5f * dt * alpha0_b,
                                 0.5f * dt * alpha1_a, 0.5f * dt * alpha1_b, st);
    const float dalpha0 = alpha0_a - alpha0_b, dalpha1 = alpha1_a - alpha1_b;
    const float theta = 0.1f + dt * 0.5f + dt * dt * (2.0f * dalpha0 + dalpha1) / 6.0f;
    CHECK(std::fabs(st.theta - theta) < 1e-6f);
    CHECK(std::fabs(st.omega(0) - (0.3f + dt * (alpha0_a + alpha1_a) / 2.0f)) < 1e-6f);
    CHECK(std::fabs(st.omega(1) - (-0.2f + dt * (alpha0_b + alpha1_b) / 2.0f)) < 1e-6f);
  }
  // Sensors per link as a bounded runtime count: an N = 4 filter with two sensors in use per
  // link gives the N = 2 filter's states bit for bit (the unused readings are never read), and
  // a count outside 2..N is refused.
  {
    ArrayGeometry<2> ga, gb;
    BenchGeometry(ga, gb);
    ArrayGeometry<4> ga4, gb4;
    for (int l = 0; l < 2; ++l) {
      const ArrayGeometry<2>& g2 = l == 0 ? ga : gb;
      ArrayGeometry<4>& g4 = l == 0 ? ga4 : gb4;
      g4.count = 2;
      for (int i = 0; i < 4; ++i) {
        g4.sensor_m[i][0] = i < 2 ? g2.sensor_m[i][0] : 9.0f;  // junk in the unused slots
        g4.sensor_m[i][1] = i < 2 ? g2.sensor_m[i][1] : -9.0f;
      }
      for (int j = 0; j < 8; ++j) g4.noise_var[j] = j < 4 ? g2.noise_var[j] : 1e9f;
      g4.joint_m[0] = g2.joint_m[0];
      g4.joint_m[1] = g2.joint_m[1];
    }
    ja::core::Settings<FixedPolicy, 2> s2;
    ja::core::Settings<FixedPolicy, 4> s4;
    CHECK((ja::core::Configure<FixedPolicy, 2>(ga, gb, 0.01f, s2)));
    CHECK((ja::core::Configure<FixedPolicy, 4>(ga4, gb4, 0.01f, s4)));
    ja::core::FilterState<FixedPolicy> st2, st4;
    ja::core::Reset(st2);
    ja::core::Reset(st4);
    bool same = true;
    for (int k = 0; k < 200; ++k) {
      Eigen::Matrix<FixedPolicy::Accel, 4, 1> a, b;
      StaticReadings<FixedPolicy>(0.7f + 0.004f * static_cast<float>(k), a, b);
      a(0) = FixedPolicy::Accel(1.5f * std::sin(0.05f * static_cast<float>(k)));
      Eigen::Matrix<FixedPolicy::Accel, 8, 1> a4, b4;
      a4.setConstant(FixedPolicy::Accel(77.0f));  // ignored
      b4.setConstant(FixedPolicy::Accel(-77.0f));
      a4.head<4>() = a;
      b4.head<4>() = b;
      ja::core::Step<FixedPolicy, 2>(s2, a, b, st2);
      ja::core::Step<FixedPolicy, 4>(s4, a4, b4, st4);
      same = same && st2.theta.raw() == st4.theta.raw() &&
             st2.omega(0).raw() == st4.omega(0).raw() && st2.omega(1).raw() == st4.omega(1).raw();
    }
    CHECK(same);
    ga4.count = 1;
    CHECK(!(ja::core::Configure<FixedPolicy, 4>(ga4, gb4, 0.01f, s4)));
    ga4.count = 5;
    CHECK(!(ja::core::Configure<FixedPolicy, 4>(ga4, gb4, 0.01f, s4)));
  }
  const unsigned ram =
      sizeof(ja::core::Settings<FixedPolicy, 2>) + sizeof(ja::core::FilterState<FixedPolicy>);
  std::printf("filter RAM (settings + state, FixedPolicy, 2+2 sensors): %u bytes\n", ram);
  CHECK(ram <= 1024);
  return ja_test::Finish("test_joint_filter");
}
