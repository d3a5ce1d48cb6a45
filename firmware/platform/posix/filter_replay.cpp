// C ABI of the joint filter for the host (jointangle `firmware` estimator, parity bench): the
// firmware core replayed on x86 over a whole recording, with the fixed-point policy the MCU runs
// (or the float build of the same source). Loaded with ctypes; no sanitizers, no allocation.
#include <stdint.h>

#include "core/joint_filter.hpp"

namespace {

// Every link is passed with kSensorsPerLink slots; its first value says how many are in use (2..4,
// the app's choice), the readings of the others are ignored (pass 0).
constexpr int kSensorsPerLink = ja::core::kMaxSensorsPerLink;
constexpr int kReadingsPerLink = 2 * kSensorsPerLink;
constexpr int kGeometryPerLink = 1 + 2 * kSensorsPerLink + 2 + kReadingsPerLink + kSensorsPerLink;
constexpr int kOutputsPerStep = 6;

using ja::core::ArrayGeometry;

/// One link's ArrayGeometry from kGeometryPerLink values (double from the host API, float as
/// the app builds it): sensors in use, then x, y per sensor slot, joint x, y (m), the noise
/// variance per reading ((m/s^2)^2), then each slot's read delay after the row's time (s).
template <class T>
ArrayGeometry<kSensorsPerLink> ReadGeometry(const T* g) {
  ArrayGeometry<kSensorsPerLink> out;
  const T count = g[0];
  out.count = count >= 0 && count <= kSensorsPerLink ? static_cast<uint8_t>(count) : 0;
  ++g;
  for (int i = 0; i < kSensorsPerLink; ++i) {
    out.sensor_m[i][0] = static_cast<float>(g[2 * i]);
    out.sensor_m[i][1] = static_cast<float>(g[2 * i + 1]);
  }
  out.joint_m[0] = static_cast<float>(g[2 * kSensorsPerLink]);
  out.joint_m[1] = static_cast<float>(g[2 * kSensorsPerLink + 1]);
  for (int j = 0; j < kReadingsPerLink; ++j)
    out.noise_var[j] = static_cast<float>(g[2 * kSensorsPerLink + 2 + j]);
  for (int i = 0; i < kSensorsPerLink; ++i)
    out.read_delay_s[i] = static_cast<float>(g[2 * kSensorsPerLink + 2 + kReadingsPerLink + i]);
  return out;
}

template <class P>
typename P::Accel FromRawQ16(int32_t raw);
template <>
ja::core::FixedPolicy::Accel FromRawQ16<ja::core::FixedPolicy>(int32_t raw) {
  return ja::core::FixedPolicy::Accel::FromRaw(raw);
}
template <>
float FromRawQ16<ja::core::FloatPolicy>(int32_t raw) {
  return static_cast<float>(raw) * (1.0f / 65536.0f);
}

template <class P>
int Replay(const double* geometry, double dt, int32_t n_steps, const int32_t* acc_q16, double* out,
           uint32_t* stats) {
  using Vec = Eigen::Matrix<typename P::Accel, kReadingsPerLink, 1>;
  ja::core::Settings<P, kSensorsPerLink> settings;
  if (!ja::core::Configure<P, kSensorsPerLink>(ReadGeometry(geometry),
                                               ReadGeometry(geometry + kGeometryPerLink),
                                               static_cast<float>(dt), settings))
    return -1;
  ja::core::FilterState<P> st;
  ja::core::Reset(st);
  for (int32_t k = 0; k < n_steps; ++k) {
    const int32_t* row = acc_q16 + static_cast<int64_t>(k) * 2 * kReadingsPerLink;
    Vec a, b;
    for (int j = 0; j < kReadingsPerLink; ++j) {
      a(j) = FromRawQ16<P>(row[j]);
      b(j) = FromRawQ16<P>(row[kReadingsPerLink + j]);
    }
    ja::core::Step<P, kSensorsPerLink>(settings, a, b, st);
    double* o = out + static_cast<int64_t>(k) * kOutputsPerStep;
    o[0] = static_cast<double>(ja::core::ToFloat(st.omega(0)));
    o[1] = static_cast<double>(ja::core::ToFloat(st.omega(1)));
    o[2] = static_cast<double>(ja::core::ToFloat(ja::core::OutputAngle(settings, st)));
    o[3] = static_cast<double>(ja::core::ToFloat(ja::core::AnalyticalAngleOf(st)));
    o[4] = static_cast<double>(ja::core::ToFloat(ja::core::CovarianceTrace(st)));
    o[5] = static_cast<double>(st.health.saturations);
  }
  stats[0] = st.health.saturations;
  stats[1] = st.health.skipped_updates;
  return 0;
}

constexpr int kRawOutputsPerStep = 6;

}  // namespace

extern "C" {

/// The fixed-point core exactly as the app drives it (firmware/app/app.cpp ConfigureFilter,
/// StepFilter, Stream), for bit-exact comparison with a board's stream. geometry: per link (a,
/// then b) the float32 ArrayGeometry the app builds, in ReadGeometry's layout (kGeometryPerLink
/// floats per link); dt: the app's 1.0f / rate. acc_q16: n_steps x 2 kReadingsPerLink
/// calibrated link-frame readings, Q15.16 raw (a's slots then b's). out_raw: n_steps x 6 int32 =
/// the streamed sample_estimate values theta Q24, omega_a Q16, omega_b Q16 (ConvertFixed, as
/// Stream), then the state's own raw theta (Q28), omega_a, omega_b (Q24). periods: n_steps sample
/// periods since the previous step (the app's StepPeriods of the frames' t_us), or NULL for 1 each.
/// stats: [saturations, skipped updates]. Returns 0, or -1 when the configuration is rejected.
int ja_filter_replay_fixed_raw_periods(const float* geometry, float dt, int32_t n_steps,
                                       const int32_t* acc_q16, const uint8_t* periods,
                                       int32_t* out_raw, uint32_t* stats) {
  using P = ja::core::FixedPolicy;
  using Vec = Eigen::Matrix<P::Accel, kReadingsPerLink, 1>;
  ja::core::Settings<P, kSensorsPerLink> settings;
  if (!ja::core::Configure<P, kSensorsPerLink>(
          ReadGeometry(geometry), ReadGeometry(geometry + kGeometryPerLink), dt, settings))
    return -1;
  ja::core::FilterState<P> st;
  ja::core::Reset(st);
  for (int32_t k = 0; k < n_steps; ++k) {
    const int32_t* row = acc_q16 + static_cast<int64_t>(k) * 2 * kReadingsPerLink;
    Vec a, b;
    for (int j = 0; j < kReadingsPerLink; ++j) {
      a(j) = P::Accel::FromRaw(row[j]);
      b(j) = P::Accel::FromRaw(row[kReadingsPerLink + j]);
    }
    ja::core::Step<P, kSensorsPerLink>(settings, a, b, st, periods == nullptr ? 1 : periods[k]);
    int32_t* o = out_raw + static_cast<int64_t>(k) * kRawOutputsPerStep;
    o[0] = ja::core::ConvertFixed<24>(ja::core::OutputAngle(settings, st)).raw();
    o[1] = ja::core::ConvertFixed<16>(st.omega(0)).raw();
    o[2] = ja::core::ConvertFixed<16>(st.omega(1)).raw();
    o[3] = st.theta.raw();
    o[4] = st.omega(0).raw();
    o[5] = st.omega(1).raw();
  }
  stats[0] = st.health.saturations;
  stats[1] = st.health.skipped_updates;
  return 0;
}

int ja_filter_raw_outputs_per_step(void) { return kRawOutputsPerStep; }

/// Replays n_steps samples through the filter. geometry: per link (a, then b) the sensors in use,
/// sensor positions (x, y per slot, m), joint (x, y, m), noise variance per reading
/// ((m/s^2)^2), read delay per slot (s): kGeometryPerLink doubles per link. acc_q16: n_steps x 2
/// kReadingsPerLink link-frame readings as Q15.16 raw counts (a's slots then b's). out: n_steps x 6
/// (w_a, w_b, theta, theta_analytical, trace P, saturations so far). stats: [saturations, skipped
/// updates]. use_fixed: 1 = FixedPolicy (the firmware), 0 = float. Returns 0, or -1 when the
/// configuration is rejected.
int ja_filter_replay(int use_fixed, const double* geometry, double dt, int32_t n_steps,
                     const int32_t* acc_q16, double* out, uint32_t* stats) {
  return use_fixed ? Replay<ja::core::FixedPolicy>(geometry, dt, n_steps, acc_q16, out, stats)
                   : Replay<ja::core::FloatPolicy>(geometry, dt, n_steps, acc_q16, out, stats);
}

/// Layout constants, so the host can check it was built for the same shapes.
int ja_filter_sensors_per_link(void) { return kSensorsPerLink; }
int ja_filter_geometry_per_link(void) { return kGeometryPerLink; }
int ja_filter_outputs_per_step(void) { return kOutputsPerStep; }
}
