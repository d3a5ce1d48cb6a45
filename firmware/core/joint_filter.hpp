// The firmware's joint filter: the paper's EKF model (Woods & Vikas; docs/design.md §3) with
// states x = [w_a, w_b, theta_ab], in a form that is cheap and robust on the ATmega2560, written
// once over a numeric policy (numeric_policy.hpp): FloatPolicy or FixedPolicy. The algorithm,
// its justification and the Q-format table are in FILTER.md; host/jointangle/estimators/mirror.py
// is the same algorithm in float64, operation for operation, and the parity tests hold the two
// together.
//
// One step (Step) with link-frame readings a_a, a_b (2N each, m/s^2), each step a function:
//  0. each reading turned to the readings' mean time (AlignReadings; docs/as-built.md): a sensor
//     sampled tau_i after the row's time, mean tau_m over every sensor of both links,
//     a_i(t_k + tau_m) ~= a_i[k] - ((tau_i - tau_m) / dt) (a_i[k] - a_i[k-1]); the state is then
//     the one at t_k + tau_m, and OutputAngle turns theta to the row's time,
//     theta(t_k) ~= theta - tau_m (w_a - w_b) (a common latency costs no reading any noise);
//  1. time update (Predict, TimeUpdate; eqs. 10, 13, 16, 17) with the angular acceleration
//     alpha = G_alpha a taken as linear over the step, from the previous readings' to these
//     (FILTER.md): w += dt (alpha_prev + alpha) / 2,
//     theta += dt (w_a - w_b) + dt^2 (2 dalpha_prev + dalpha) / 6 (dalpha = alpha_a - alpha_b),
//     P^- = Phi P Phi^T + Q with Phi = I + A dt, Q = diag(q_a, q_b, 0);
//  2. measurement at x^- (Measure; eqs. 11, 14, 15): y = z - h(x^-), sparse H, and R_k = V Q^ V^T
//     (MeasurementNoise; eq. 18) from blocks derived at configuration (only R(theta) M_b
//     R(theta)^T and -R(theta) c_b vary);
//  3. decorrelation R_k = L D L^T in the order (z3, z4, z1, z2): y~ = L^-1 y, H~ = L^-1 H
//     (Decorrelate);
//  4. sequential scalar updates (AngleRowsUpdate, RowUpdate, SumUpdate): p = P h~^T,
//     s = h~ p + D_m, k = p / s, x += k (y~_m - h~_m (x - x^-)), P -= k p^T (upper triangle,
//     mirrored): the batch EKF update without a 4x4 solve;
//  5. theta wrapped to (-pi, pi], the health (FinishStep); the analytical estimate (eq. 12)
//     alongside.
// Initialisation on the first step (and after Reset(); Initialise): theta from eq. 12, w = 0, and
// the omega^2 rows held back for kOmega2HoldS so theta's motion gives w its sign first; in their
// first step a measurement of w_a + w_b from the readings' magnitudes may take their place
// (ReleaseSum).
#pragma once

#include <stdint.h>

#include "config.hpp"
#include "fixed_eigen.hpp"
#include "numeric_policy.hpp"

// Profiling hook: a bench may define JA_STEP_PROFILE(id) to time each section of Step (ids
// 20..25 for the fixed build, 30..35 for float); empty otherwise.
#if defined(JA_STEP_PROFILE)
#include <type_traits>
#define JA_STEP_MARK(id) \
  JA_STEP_PROFILE((id) + (std::is_same<typename P::Gain, float>::value ? 10 : 0))
#else
#define JA_STEP_MARK(id)
#endif

namespace ja {
namespace core {

constexpr float kPi = 3.14159265358979f;
constexpr float kOmegaVariance0 = 1.0f;   // (rad/s)^2: initial P for w_a, w_b
constexpr float kThetaVariance0 = 0.01f;  // rad^2: initial P for theta when eq. 12 is trusted
constexpr float kInitMinProduct = 0.25f;  // (m/s^2)^2: |F^a a^a| |F^b a^b| to trust eq. 12
constexpr float kOmega2HoldS = 0.25f;     // s: omega^2 rows wait this long after initialising

/// The most sensors per link the filter takes (its term masks have 8 bits: 2 readings each).
constexpr int kMaxSensorsPerLink = 4;

/// One link's sensor array as configured (float, configuration time only): the first `count`
/// of N slots (2 <= count <= N <= kMaxSensorsPerLink); the readings of the others are ignored.
template <int N>
struct ArrayGeometry {
  float sensor_m[N][2];    // sensor positions r_i in the link frame, m
  float joint_m[2];        // joint O in the link frame, m
  float noise_var[2 * N];  // Q^ diagonal per reading (x, y of each sensor), (m/s^2)^2
  // When each sensor's sample of row k is taken, after the row's time t_k (negative: before
  // it, e.g. a reading's mean age at the read), s; all equal = a common latency (OutputAngle),
  // differences = skew (AlignReadings).
  float read_delay_s[N] = {};
  uint8_t count = N;  // sensors in use (slots 0..count-1)
};

/// Array matrices of one link (docs/design.md §3), in the policy's coefficient type.
template <class P, int N>
struct LinkArray {
  Eigen::Matrix<typename P::Coef, 1, 2 * N> g_omega2;  // G_w2 row: w^2 = G_w2 a, 1/(m)
  // (dt / 2) G_alpha: half of one period's angular velocity increment, h = (dt / 2) G_alpha a, s/m
  Eigen::Matrix<typename P::DtCoef, 1, 2 * N> dt_g_alpha;
  Eigen::Matrix<typename P::Coef, 2, 2 * N> f;  // F: joint acceleration a_O = F a, 1
  // The same rows as Step evaluates them (SparseRows): the non-zero coefficients of F row 0,
  // F row 1 and G_w2, one row after the other, and which readings they multiply (bit j of
  // term_mask[r]: reading j; half of them are zero for an array along its link's axis); those of
  // (dt / 2) G_alpha.
  typename P::Coef terms[3 * 2 * N];
  uint8_t term_mask[3];
  typename P::DtCoef dt_terms[2 * N];
  uint8_t dt_term_mask[1];
};

/// The part of the decorrelation (step 3) that depends only on R33, R34, R44, r13, r14, r11:
/// 1/D0, l10, r~14, 1/D1, D0/D1, l20, l21, D2, 1/D2 (DecorrelateFixedPart).
template <class P>
struct DecorrelationFixedPart {
  typename P::Inverse i0, i1, i2;
  typename P::Factor l10, l20, l21;
  typename P::Noise r14t, d2;
  typename P::Noise rho;  // D0 / D1, the weight of z~4 against z3 in the angle-rows update
};

/// Everything the step needs that does not change between steps: derived once (Configure).
template <class P, int N>
struct Settings {
  LinkArray<P, N> a, b;
  // (tau_i - tau_m) / dt per reading (x, y of sensor i), clamped to [-1, 1] (AlignReadings); bit
  // j of read_lag_mask[l]: reading j's is non-zero (none on either link: step 0 is skipped, a
  // board that samples all sensors at once).
  typename P::Lag read_lag[2][2 * N];
  uint8_t read_lag_mask[2];
  typename P::Time output_lead;      // -tau_m, s: theta turned to the row's time (OutputAngle)
  typename P::Time dt;               // s
  typename P::Time dt_third;         // dt / 3, s: the time update's alpha-slope term
  typename P::Cov q_a, q_b;          // dt^2 G_alpha Q^ G_alpha^T (eq. 17)
  typename P::Noise r11, r22;        // G_w2 Q^ G_w2^T
  typename P::Noise r13[2];          // G_w2^a Q^a F^a^T
  typename P::Noise c_b[2];          // F^b Q^b G_w2^b^T
  typename P::Noise m_a[3], m_b[3];  // F Q^ F^T as (00, 01, 11)
  // R33 block per step (double angle): R(t) M_b R(t)^T = mean I + [[e, f], [f, -e]] with
  // e = dif cos 2t + m_b01 sin 2t, f = m_b01 cos 2t - dif sin 2t (mean, dif = (m_b00 +- m_b11)/2).
  typename P::Noise r33_0, r44_0;             // m_a00 + mean, m_a11 + mean
  typename P::Noise mb_dif;                   // (m_b00 - m_b11) / 2
  typename P::Accel init_min_product2;        // kInitMinProduct^2
  typename P::Cov p_omega0, p_theta0, p_one;  // initial variances
  uint16_t hold_steps;                        // round(kOmega2HoldS / dt)
  // The omega^2 rows' first step (ReleaseSum): r11 / 4, r22 / 4, and sqrt(r11),
  // sqrt(r22) (1/s^2, the readings' omega^2 noise) as the floor of |w^2| in sigma(|w|).
  typename P::Noise r11_quarter, r22_quarter;
  typename P::Accel z_floor_a, z_floor_b;
  typename P::Angle pi, two_pi;  // for the wrap
  // M_b01 = 0 and dif = 0 (M_b a multiple of I: an array along its link's axis with equal x and
  // y noise, every scenario rig): R33, R34, R44 do not depend on theta, so neither do 1/D0,
  // l10, D1, 1/D1, l20, l21, D2, 1/D2; Configure computes them once, with Step's arithmetic.
  bool decorrelation_fixed;
  DecorrelationFixedPart<P> decorrelation;
};

/// Filter health, refreshed every step.
template <class P>
struct Health {
  typename P::Accel innovation[4];  // decorrelated innovations y~ (z3, z4, z1, z2 order)
  uint16_t saturations;             // fixed-point saturations since Reset() (wraps)
  uint16_t skipped_updates;         // scalar updates skipped because s <= 0 (wraps)
  uint32_t steps;                   // sample periods since Reset() (= steps on schedule)
};

/// The filter's state; the caller owns it (static storage on the MCU).
template <class P>
struct FilterState {
  Eigen::Matrix<typename P::Omega, 2, 1> omega;  // [w_a, w_b], rad/s
  // The previous step's half increments h = (dt / 2) G_alpha a of both links (the time update's
  // alpha at the start of the step), rad/s.
  typename P::Omega half_dw[2];
  typename P::Angle theta;                 // theta_ab, rad, (-pi, pi]
  Eigen::Matrix<typename P::Cov, 3, 3> p;  // covariance of [w_a, w_b, theta]
  // The joint accelerations of this step's readings, z^a = F^a a^a and u = F^b a^b (eq. 8):
  // AnalyticalAngleOf forms eq. 12 from them when something reads the analytical angle (its
  // cross and dot products and the atan2, ~1 500 AVR cycles, are left out of Step: the
  // high-rate frame never carries the angle).
  typename P::Accel analytical_za[2], analytical_u[2];
  // The previous step's readings as read (before AlignReadings), per link, 2 per slot.
  typename P::Accel previous[2][2 * kMaxSensorsPerLink];
  Health<P> health;
  bool initialised;
  bool omega2_rows_on;  // the omega^2 rows have had their first update since initialising
};

namespace detail {

/// Fills the link's term lists (LinkArray::terms, dt_terms) from its matrices: the non-zero
/// coefficients in ascending reading order, row after row.
template <class P, int N>
void CollectTerms(LinkArray<P, N>& link) {
  static_assert(2 * N <= 8, "term masks have 8 bits");
  using Coef = typename P::Coef;
  using DtCoef = typename P::DtCoef;
  uint8_t n = 0;
  for (int r = 0; r < 3; ++r) {
    uint8_t mask = 0;
    for (int j = 0; j < 2 * N; ++j) {
      const Coef v = r < 2 ? link.f(r, j) : link.g_omega2(0, j);
      if (v == Coef(0)) continue;
      link.terms[n++] = v;
      mask = static_cast<uint8_t>(mask | (1u << j));
    }
    link.term_mask[r] = mask;
  }
  uint8_t count = 0, mask = 0;
  for (int j = 0; j < 2 * N; ++j) {
    const DtCoef v = link.dt_g_alpha(0, j);
    if (v == DtCoef(0)) continue;
    link.dt_terms[count++] = v;
    mask = static_cast<uint8_t>(mask | (1u << j));
  }
  link.dt_term_mask[0] = mask;
}

/// The first kRows of (F row 0, F row 1, G_w2) times the link's readings (eqs. 8, 9).
template <int kRows, class P, int N>
JA_FORCE_INLINE void LinkRows(const LinkArray<P, N>& link,
                              const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc,
                              typename P::Accel* out) {
  SparseRows<kRows>(link.terms, link.term_mask, acc.data(), out);
}

/// ((dt / 2) G_alpha) a: half the link's angular velocity increment over one period at these
/// readings' alpha (eqs. 10, 13; TimeUpdate adds the previous step's half and this one's).
template <class P, int N>
JA_FORCE_INLINE typename P::Omega LinkOmegaIncrement(
    const LinkArray<P, N>& link, const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc) {
  typename P::Omega out[1];
  SparseRows<1>(link.dt_terms, link.dt_term_mask, acc.data(), out);
  return out[0];
}

/// G and F of one link from its geometry (float). Since sum_i (r_i - rbar) = 0, D~^T E = D~^T,
/// so G = D~^+ E = D~^T / sum|r_i - rbar|^2 (eq. 9) and F = F_m + D(r_O - rbar) G (eq. 8).
/// Returns false when the array is degenerate (all sensors within 1 mm).
template <int N>
bool DeriveArrayFloat(const ArrayGeometry<N>& geo, float g[2][2 * N], float f[2][2 * N]) {
  static_assert(N >= 2 && N <= kMaxSensorsPerLink, "2 to kMaxSensorsPerLink sensors per link");
  const int n = geo.count;
  if (n < 2 || n > N) return false;
  for (int c = 0; c < 2 * N; ++c) g[0][c] = g[1][c] = f[0][c] = f[1][c] = 0.0f;
  float mean[2] = {0.0f, 0.0f};
  for (int i = 0; i < n; ++i) {
    mean[0] += geo.sensor_m[i][0] / static_cast<float>(n);
    mean[1] += geo.sensor_m[i][1] / static_cast<float>(n);
  }
  float spread2 = 0.0f;
  for (int i = 0; i < n; ++i) {
    const float dx = geo.sensor_m[i][0] - mean[0], dy = geo.sensor_m[i][1] - mean[1];
    spread2 += dx * dx + dy * dy;
  }
  if (!(spread2 >= 1e-6f)) return false;
  for (int i = 0; i < n; ++i) {
    const float dx = geo.sensor_m[i][0] - mean[0], dy = geo.sensor_m[i][1] - mean[1];
    // D(r) = [[-r1, -r2], [-r2, r1]] is symmetric: G block i = D(r_i - rbar) / spread2.
    g[0][2 * i] = -dx / spread2;
    g[0][2 * i + 1] = -dy / spread2;
    g[1][2 * i] = -dy / spread2;
    g[1][2 * i + 1] = dx / spread2;
  }
  const float ox = geo.joint_m[0] - mean[0], oy = geo.joint_m[1] - mean[1];
  for (int c = 0; c < 2 * n; ++c) {
    const float fm0 = (c % 2 == 0) ? 1.0f / static_cast<float>(n) : 0.0f;
    const float fm1 = (c % 2 == 1) ? 1.0f / static_cast<float>(n) : 0.0f;
    f[0][c] = fm0 + (-ox * g[0][c] - oy * g[1][c]);
    f[1][c] = fm1 + (-oy * g[0][c] + ox * g[1][c]);
  }
  return true;
}

/// A configuration constant in type T; a value outside a Fixed format's range counts as a
/// saturation (Configure checks the counter).
template <class T>
struct FromFloatImpl {
  static T Do(float v) { return T(v); }
};
template <int F>
struct FromFloatImpl<Fixed<F>> {
  static Fixed<F> Do(float v) {
    const Fixed<F> r(v);
    if (r.raw() == 0x7FFFFFFF || r.raw() == -0x7FFFFFFF - 1) ++SaturationCount();
    return r;
  }
};
template <int F>
struct FromFloatImpl<Fixed16<F>> {
  static Fixed16<F> Do(float v) {
    return Fixed16<F>::FromRaw(Fixed16<F>::Saturate16(FromFloatImpl<Fixed<F>>::Do(v).raw()));
  }
};
template <class T>
inline T FromFloatValue(float v) {
  return FromFloatImpl<T>::Do(v);
}

/// theta wrapped to (-pi, pi] after a step of less than a turn (pi, 2 pi from Configure).
template <class A>
inline A WrapAngle(A theta, A pi, A two_pi) {
  if (theta > pi) return theta - two_pi;
  if (!(theta > -pi)) return theta + two_pi;
  return theta;
}

}  // namespace detail

namespace detail {

/// The theta-independent part of the decorrelation (step 3, Gram-Schmidt in the order z3, z4, z1,
/// z2): D0 = R33, l10 = R34 / D0, D1 = R44 - l10 R34, r~14 = r14 - l10 r13, l20 = r13 / D0,
/// l21 = r~14 / D1, D2 = r11 - l20 r13 - l21 r~14, 1/D0, 1/D1, 1/D2 and rho = D0 / D1 (for
/// AngleRowsUpdate). l10 = 0 (R34 = 0) and l21 = 0 (then also r14 = 0) leave their rows
/// unchanged: the terms are skipped, exactly.
template <class P>
JA_FORCE_INLINE void DecorrelateFixedPart(typename P::Noise r33, typename P::Noise r34,
                                          typename P::Noise r44, typename P::Noise r13,
                                          typename P::Noise r14, typename P::Noise r11,
                                          typename P::Inverse& i0, typename P::Inverse& i1,
                                          typename P::Inverse& i2, typename P::Factor& l10,
                                          typename P::Factor& l20, typename P::Factor& l21,
                                          typename P::Noise& r14t, typename P::Noise& d2,
                                          typename P::Noise& rho) {
  using Noise = typename P::Noise;
  using Factor = typename P::Factor;
  using Inverse = typename P::Inverse;
  i0 = Recip<Inverse>(r33);
  l10 = Mul<Factor>(r34, i0);
  Noise d1 = r44;
  r14t = r14;
  if (!(l10 == Factor(0))) {
    Sum<Noise, Factor, Noise> a, b;
    a.AddValue(r44);
    a.Subtract(l10, r34);
    d1 = a.Result();
    b.AddValue(r14);
    b.Subtract(l10, r13);
    r14t = b.Result();
  }
  i1 = Recip<Inverse>(d1);
  rho = Mul<Noise>(r33, i1);
  l20 = Mul<Factor>(r13, i0);
  l21 = Mul<Factor>(r14t, i1);
  Sum<Noise, Factor, Noise> a;
  a.AddValue(r11);
  a.Subtract(l20, r13);
  if (!(l21 == Factor(0))) a.Subtract(l21, r14t);
  d2 = a.Result();
  i2 = Recip<Inverse>(d2);
}

}  // namespace detail

/// Derives the filter's settings from both arrays' geometry, the sample period and the noise
/// (configuration time, float). Returns false if the geometry is degenerate or a derived
/// constant does not fit its Q format (FILTER.md).
template <class P, int N>
bool Configure(const ArrayGeometry<N>& geo_a, const ArrayGeometry<N>& geo_b, float dt_s,
               Settings<P, N>& out) {
  using Noise = typename P::Noise;
  using Cov = typename P::Cov;
  if (!(dt_s > 0.0f && dt_s < 1.0f)) return false;
  const uint16_t saturations_before = SaturationCount();
  float g[2][2][2 * N], f[2][2][2 * N];
  if (!detail::DeriveArrayFloat<N>(geo_a, g[0], f[0])) return false;
  if (!detail::DeriveArrayFloat<N>(geo_b, g[1], f[1])) return false;
  LinkArray<P, N>* links[2] = {&out.a, &out.b};
  const ArrayGeometry<N>* geos[2] = {&geo_a, &geo_b};
  float q[2] = {0, 0}, r[2] = {0, 0}, c[2][2] = {{0, 0}, {0, 0}}, m[2][3] = {{0, 0, 0}, {0, 0, 0}};
  for (int l = 0; l < 2; ++l) {
    for (int j = 0; j < 2 * N; ++j) {
      if (j >= 2 * geos[l]->count) {  // an unused slot: zero coefficients, never read by Step
        links[l]->g_omega2(0, j) = typename P::Coef(0);
        links[l]->dt_g_alpha(0, j) = typename P::DtCoef(0);
        links[l]->f(0, j) = typename P::Coef(0);
        links[l]->f(1, j) = typename P::Coef(0);
        continue;
      }
      const float var = geos[l]->noise_var[j];
      links[l]->g_omega2(0, j) = detail::FromFloatValue<typename P::Coef>(g[l][0][j]);
      links[l]->dt_g_alpha(0, j) =
          detail::FromFloatValue<typename P::DtCoef>(0.5f * dt_s * g[l][1][j]);
      links[l]->f(0, j) = detail::FromFloatValue<typename P::Coef>(f[l][0][j]);
      links[l]->f(1, j) = detail::FromFloatValue<typename P::Coef>(f[l][1][j]);
      q[l] += g[l][1][j] * g[l][1][j] * var;
      r[l] += g[l][0][j] * g[l][0][j] * var;
      c[l][0] += f[l][0][j] * var * g[l][0][j];
      c[l][1] += f[l][1][j] * var * g[l][0][j];
      m[l][0] += f[l][0][j] * var * f[l][0][j];
      m[l][1] += f[l][0][j] * var * f[l][1][j];
      m[l][2] += f[l][1][j] * var * f[l][1][j];
    }
  }
  for (int l = 0; l < 2; ++l) detail::CollectTerms(*links[l]);
  // tau_m: the mean sample time of every sensor of both links, after the row's time.
  float tau_sum = 0.0f;
  for (int l = 0; l < 2; ++l) {
    for (int i = 0; i < geos[l]->count; ++i) tau_sum += geos[l]->read_delay_s[i];
  }
  const float tau_m = tau_sum / static_cast<float>(geos[0]->count + geos[1]->count);
  for (int l = 0; l < 2; ++l) {
    out.read_lag_mask[l] = 0;
    for (int i = 0; i < N; ++i) {
      float lag = i < geos[l]->count ? (geos[l]->read_delay_s[i] - tau_m) / dt_s : 0.0f;
      lag = lag > 1.0f ? 1.0f : (lag < -1.0f ? -1.0f : lag);  // beyond a period: the nearest row
      const typename P::Lag v = detail::FromFloatValue<typename P::Lag>(lag);
      out.read_lag[l][2 * i] = out.read_lag[l][2 * i + 1] = v;
      if (!(v == typename P::Lag(0))) out.read_lag_mask[l] |= static_cast<uint8_t>(3u << (2 * i));
    }
  }
  out.output_lead = detail::FromFloatValue<typename P::Time>(-tau_m);
  out.dt = detail::FromFloatValue<typename P::Time>(dt_s);
  out.dt_third = detail::FromFloatValue<typename P::Time>(dt_s / 3.0f);
  out.q_a = detail::FromFloatValue<Cov>(dt_s * dt_s * q[0]);
  out.q_b = detail::FromFloatValue<Cov>(dt_s * dt_s * q[1]);
  out.r11 = detail::FromFloatValue<Noise>(r[0]);
  out.r22 = detail::FromFloatValue<Noise>(r[1]);
  for (int i = 0; i < 2; ++i) {
    out.r13[i] = detail::FromFloatValue<Noise>(c[0][i]);
    out.c_b[i] = detail::FromFloatValue<Noise>(c[1][i]);
  }
  for (int i = 0; i < 3; ++i) {
    out.m_a[i] = detail::FromFloatValue<Noise>(m[0][i]);
    out.m_b[i] = detail::FromFloatValue<Noise>(m[1][i]);
  }
  const float mean_b = 0.5f * (m[1][0] + m[1][2]);
  out.r33_0 = detail::FromFloatValue<Noise>(m[0][0] + mean_b);
  out.r44_0 = detail::FromFloatValue<Noise>(m[0][2] + mean_b);
  out.mb_dif = detail::FromFloatValue<Noise>(0.5f * (m[1][0] - m[1][2]));
  out.init_min_product2 =
      detail::FromFloatValue<typename P::Accel>(kInitMinProduct * kInitMinProduct);
  out.p_omega0 = detail::FromFloatValue<Cov>(kOmegaVariance0);
  out.p_theta0 = detail::FromFloatValue<Cov>(kThetaVariance0);
  out.p_one = detail::FromFloatValue<Cov>(1.0f);
  out.pi = detail::FromFloatValue<typename P::Angle>(kPi);
  out.two_pi = detail::FromFloatValue<typename P::Angle>(2.0f * kPi);
  const float hold = kOmega2HoldS / dt_s + 0.5f;
  out.hold_steps = hold >= 65535.0f ? 65535u : static_cast<uint16_t>(hold);
  out.r11_quarter = detail::FromFloatValue<Noise>(0.25f * r[0]);
  out.r22_quarter = detail::FromFloatValue<Noise>(0.25f * r[1]);
  out.z_floor_a = detail::FromFloatValue<typename P::Accel>(sqrtf(r[0]));
  out.z_floor_b = detail::FromFloatValue<typename P::Accel>(sqrtf(r[1]));
  // R33 = r33_0 + e, R44 = r44_0 - e, R34 = m_a01 + (m_b01 cos 2t - dif sin 2t): with e = 0 and
  // the m_b01, dif terms skipped, Step's sums give exactly these (the same arithmetic).
  out.decorrelation_fixed = out.m_b[1] == Noise(0) && out.mb_dif == Noise(0);
  if (out.decorrelation_fixed) {
    DecorrelationFixedPart<P>& o = out.decorrelation;
    detail::DecorrelateFixedPart<P>(out.r33_0 + Noise(0), out.m_a[1], out.r44_0 - Noise(0),
                                    out.r13[0], out.r13[1], out.r11, o.i0, o.i1, o.i2, o.l10, o.l20,
                                    o.l21, o.r14t, o.d2, o.rho);
  }
  const bool fits = SaturationCount() == saturations_before;
  SaturationCount() = saturations_before;
  return fits;
}

/// Forgets the estimate: the next Step re-initialises (start-up, or after a fault clears).
template <class P>
void Reset(FilterState<P>& st) {
  using Cov = typename P::Cov;
  st.omega.setConstant(typename P::Omega(0));
  st.half_dw[0] = typename P::Omega(0);
  st.half_dw[1] = typename P::Omega(0);
  st.theta = typename P::Angle(0);
  st.p.setConstant(Cov(0));
  for (int i = 0; i < 2; ++i) {
    st.analytical_za[i] = typename P::Accel(0);
    st.analytical_u[i] = typename P::Accel(0);
  }
  for (int i = 0; i < 4; ++i) st.health.innovation[i] = typename P::Accel(0);
  for (int l = 0; l < 2; ++l) {
    for (int j = 0; j < 2 * kMaxSensorsPerLink; ++j) st.previous[l][j] = typename P::Accel(0);
  }
  st.health.saturations = 0;
  st.health.skipped_updates = 0;
  st.health.steps = 0;
  st.initialised = false;
  st.omega2_rows_on = false;
}

namespace detail {

/// (P h~^T)_I = P_I0 h0 + P_I1 h1 + P_I2 h2, the zero terms left out (kH0, kH1).
template <bool kH0, bool kH1, int I, class Cross, class Cov, class Row>
JA_FORCE_INLINE Cross RowTimesP(const Eigen::Matrix<Cov, 3, 3>& p, Row h0, Row h1, Row h2) {
  Sum<Cross, Cov, Row> acc;
  if (kH0) acc.Add(p(I, 0), h0);
  if (kH1) acc.Add(p(I, 1), h1);
  acc.Add(p(I, 2), h2);
  return acc.Result();
}

/// P_ij = P_ji = P_ij - k_i p_j (one entry of the rank-one downdate).
template <int I, int J, class Cov, class Gain, class Cross>
JA_FORCE_INLINE void DowndateEntry(Eigen::Matrix<Cov, 3, 3>& p, const Gain* k, const Cross* ph) {
  const Cov v = p(I, J) - Mul<Cov>(k[I], ph[J]);
  p(I, J) = v;
  if (I != J) p(J, I) = v;
}

/// One scalar measurement update (step 4) with row h~ = (h0, h1, h2), innovation y, variance d.
/// kH0 / kH1: whether h0 / h1 are non-zero (the rows of z3 and z4 have h2 only). The state comes
/// first and h0 last: on AVR the first 18 bytes of arguments travel in registers, the rest on
/// the stack, where every access to the state through its pointer cost a frame adjustment.
template <bool kH0, bool kH1, class P>
inline void ScalarUpdate(FilterState<P>& st, typename P::Noise d, typename P::Accel y,
                         typename P::Row h2, typename P::Row h1, typename P::Row h0) {
  using Cov = typename P::Cov;
  using Cross = typename P::Cross;
  using Gain = typename P::Gain;
  using Row = typename P::Row;
  Eigen::Matrix<Cov, 3, 3>& p = st.p;
  // p = P h~^T (written out, as the downdate below)
  Cross ph[3];
  ph[0] = RowTimesP<kH0, kH1, 0, Cross>(p, h0, h1, h2);
  ph[1] = RowTimesP<kH0, kH1, 1, Cross>(p, h0, h1, h2);
  ph[2] = RowTimesP<kH0, kH1, 2, Cross>(p, h0, h1, h2);
  // s = h~ p + D
  Sum<typename P::Noise, Row, Cross> s_acc;
  if (kH0) s_acc.Add(h0, ph[0]);
  if (kH1) s_acc.Add(h1, ph[1]);
  s_acc.Add(h2, ph[2]);
  s_acc.AddValue(d);
  const typename P::Noise s = s_acc.Result();
  if (!(s > typename P::Noise(0))) {
    ++st.health.skipped_updates;
    return;
  }
  const typename P::Inverse inv = Recip<typename P::Inverse>(s);
  Gain k[3];
  k[0] = Mul<Gain>(ph[0], inv);
  k[1] = Mul<Gain>(ph[1], inv);
  k[2] = Mul<Gain>(ph[2], inv);
  // x += k y
  st.omega(0) = st.omega(0) + Mul<typename P::Omega>(k[0], y);
  st.omega(1) = st.omega(1) + Mul<typename P::Omega>(k[1], y);
  st.theta = st.theta + Mul<typename P::Angle>(k[2], y);
  // P -= k p^T on the upper triangle, mirrored (P stays exactly symmetric). Written out: every
  // entry at a constant offset (AVR: no index arithmetic per entry).
  DowndateEntry<0, 0>(p, k, ph);
  DowndateEntry<0, 1>(p, k, ph);
  DowndateEntry<0, 2>(p, k, ph);
  DowndateEntry<1, 1>(p, k, ph);
  DowndateEntry<1, 2>(p, k, ph);
  DowndateEntry<2, 2>(p, k, ph);
}

/// The two angle rows z3 and z~4 (h~ = (0, 0, c1) and (0, 0, c2), independent noise D0 and D1,
/// both innovations at x^-) as one exact update. Rows that see only theta add their information
/// c^2/D and c y/D; scaled by D0 (rho = D0/D1):
///   g = c1^2 + rho c2^2,  nu = c1 y3 + rho c2 y~4,  s = D0 + g P22,
///   x += P[:,2] nu / s,
///   P_ij -= P_i2 P_j2 g / s  (i, j in {0, 1}),  P_i2 *= D0 / s  (i = 0, 1, 2).
/// In exact arithmetic this is the two sequential scalar updates (and so the batch EKF's): after
/// a theta-only row the angle column of P is only scaled, by D0/s = 1 - g P22/s. One reciprocal
/// and 21 products instead of two reciprocals and 33, and P22 is scaled, not downdated by a
/// difference, so rounding cannot turn it negative. An update with s <= 0 is skipped, counted.
template <class P>
inline void AngleRowsUpdate(FilterState<P>& st, typename P::Noise d0, typename P::Noise rho,
                            typename P::Accel y3, typename P::Row c1, typename P::Accel y4,
                            typename P::Row c2) {
  using Accel = typename P::Accel;
  using Cov = typename P::Cov;
  using Cross = typename P::Cross;
  using Gain = typename P::Gain;
  using Noise = typename P::Noise;
  using Row = typename P::Row;
  Eigen::Matrix<Cov, 3, 3>& p = st.p;
  const Row c2w = Mul<Row>(c2, rho);
  Sum<Row, Row, Row> g_acc;
  g_acc.Add(c1, c1);
  g_acc.Add(c2w, c2);
  const Row g = g_acc.Result();
  // nu in the Row format: c y is finer than the readings' lsb when |c| < 1 (slow joints).
  Sum<Row, Row, Accel> nu_acc;
  nu_acc.Add(c1, y3);
  nu_acc.Add(c2w, y4);
  const Row nu = nu_acc.Result();
  Sum<Noise, Cov, Row> s_acc;
  s_acc.AddValue(d0);
  s_acc.Add(p(2, 2), g);
  const Noise s = s_acc.Result();
  if (!(s > Noise(0))) {
    ++st.health.skipped_updates;
    return;
  }
  const typename P::Inverse inv = Recip<typename P::Inverse>(s);
  const Cov beta = Mul<Cov>(d0, inv);      // D0 / s
  const Accel nu_s = Mul<Accel>(nu, inv);  // nu / s
  const Cov p02 = p(0, 2), p12 = p(1, 2), p22 = p(2, 2);
  const Gain k0 = Mul<Gain>(Mul<Cross>(p02, g), inv);  // P_i2 g / s
  const Gain k1 = Mul<Gain>(Mul<Cross>(p12, g), inv);
  st.omega(0) = st.omega(0) + Mul<typename P::Omega>(p02, nu_s);
  st.omega(1) = st.omega(1) + Mul<typename P::Omega>(p12, nu_s);
  st.theta = st.theta + Mul<typename P::Angle>(p22, nu_s);
  const Cov p00 = p(0, 0) - Mul<Cov>(k0, p02);
  const Cov p01 = p(0, 1) - Mul<Cov>(k0, p12);
  const Cov p11 = p(1, 1) - Mul<Cov>(k1, p12);
  p(0, 0) = p00;
  p(0, 1) = p01;
  p(1, 0) = p01;
  p(1, 1) = p11;
  const Cov q02 = Mul<Cov>(p02, beta), q12 = Mul<Cov>(p12, beta);
  p(0, 2) = q02;
  p(2, 0) = q02;
  p(1, 2) = q12;
  p(2, 1) = q12;
  p(2, 2) = Mul<Cov>(p22, beta);
}

/// y~ - h~ (x - x^-): row (h0, h1, h2)'s innovation at the current state, x^- = (w0m, w1m, thm)
/// the state before the first update (kH0 / kH1: whether h0 / h1 are non-zero).
template <bool kH0, bool kH1, class P>
JA_FORCE_INLINE typename P::Accel Innovation(typename P::Accel y, typename P::Row h2,
                                             typename P::Row h1, typename P::Row h0,
                                             const FilterState<P>& st, typename P::Omega w0m,
                                             typename P::Omega w1m, typename P::Angle thm) {
  using Accel = typename P::Accel;
  Sum<Accel, typename P::Row, typename P::Angle> a;
  a.AddValue(y);
  a.Subtract(h2, st.theta - thm);
  if (!kH0 && !kH1) return a.Result();
  Sum<Accel, typename P::Row, typename P::Omega> b;
  if (kH0) b.Subtract(h0, st.omega(0) - w0m);
  if (kH1) b.Subtract(h1, st.omega(1) - w1m);
  return a.Result() + b.Result();
}

}  // namespace detail

/// The analytical estimate (eq. 12) is theta = atan2(cross, dot) with cross = z1 u2 - z2 u1 and
/// dot = z1 u1 + z2 u2 of the joint accelerations z^a = F^a a^a, u = F^b a^b (eq. 8). Step keeps
/// z^a and u of its readings in the state, and AnalyticalAngleOf forms cross, dot and the atan2
/// when something reads the angle (the `estimate` message, the x86 replay); the app's
/// analytical-only filter kind (App::StepAnalytical) calls AnalyticalTerms alone. Force-inlined
/// into the caller's locals: Step's cycle count must not pay for a call or for its outputs going
/// through memory.
///
/// cross and dot of the joint accelerations z^a, u.
template <class P>
JA_FORCE_INLINE void AnalyticalCrossDot(const typename P::Accel* za, const typename P::Accel* u,
                                        typename P::Accel& cross, typename P::Accel& dot) {
  using Accel = typename P::Accel;
  Sum<Accel, Accel, Accel> cross_acc, dot_acc;
  cross_acc.Add(za[0], u[1]);
  cross_acc.Subtract(za[1], u[0]);
  dot_acc.Add(za[0], u[0]);
  dot_acc.Add(za[1], u[1]);
  cross = cross_acc.Result();
  dot = dot_acc.Result();
}

/// eq. 12's terms of the readings into the state: z^a = F^a a^a, u = F^b a^b (eq. 8).
template <class P, int N>
JA_FORCE_INLINE void AnalyticalTerms(const Settings<P, N>& c,
                                     const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_a,
                                     const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_b,
                                     FilterState<P>& st) {
  detail::LinkRows<2>(c.a, acc_a, st.analytical_za);
  detail::LinkRows<2>(c.b, acc_b, st.analytical_u);
}

/// The analytical estimate (eq. 12) of the last step's readings: atan2(cross, dot). (A
/// saturation of cross or dot, |z^a| |u| >= 32 768 (m/s^2)^2, counts in SaturationCount(), not
/// in the step's health.)
template <class P>
inline typename P::Angle AnalyticalAngleOf(const FilterState<P>& st) {
  typename P::Accel cross, dot;
  AnalyticalCrossDot<P>(st.analytical_za, st.analytical_u, cross, dot);
  return Atan2To<typename P::Angle>(cross, dot);
}

/// The trace of the state covariance P (filter health), formed where it is read (the `estimate`
/// message, the x86 replay) rather than in every Step.
template <class P>
inline typename P::Noise CovarianceTrace(const FilterState<P>& st) {
  using Noise = typename P::Noise;
  return Cast<Noise>(st.p(0, 0)) + Cast<Noise>(st.p(1, 1)) + Cast<Noise>(st.p(2, 2));
}

/// theta at the row's time, what a board streams: the state is at the readings' mean sample
/// time t_k + tau_m (AlignReadings), so theta(t_k) ~= theta - tau_m (w_a - w_b) =
/// theta + output_lead (w_a - w_b), wrapped (the same kinematics as TimeUpdate's first term).
template <class P, int N>
inline typename P::Angle OutputAngle(const Settings<P, N>& c, const FilterState<P>& st) {
  if (c.output_lead == typename P::Time(0)) return st.theta;
  Sum<typename P::Angle, typename P::Time, typename P::Omega> turn;
  turn.Add(c.output_lead, st.omega(0) - st.omega(1));
  return detail::WrapAngle(st.theta + turn.Result(), c.pi, c.two_pi);
}

/// The most sample periods one step predicts over (a longer gap is predicted over this many).
constexpr uint8_t kMaxStepPeriods = 8;

namespace detail {

/// One period's time update (eqs. 10, 13, 16, 17) with the angular acceleration alpha = G_alpha a
/// of each link linear over the period, from alpha0 at its start to alpha1 at its end, given as
/// half increments h = (dt / 2) alpha (LinkOmegaIncrement, formed once per step):
///   w(t + dt) = w + dt (alpha0 + alpha1) / 2 = w + h0 + h1,
///   theta(t + dt) = theta + dt (w_a - w_b) + dt^2 (2 dalpha0 + dalpha1) / 6
///                 = theta + dt (w_a - w_b) + (dt / 3) (2 dh0 + dh1)   (dh = h_a - h_b),
/// the exact integrals of the model's kinematics (theta' = w_a - w_b, w' = alpha). Taking alpha
/// at the period's end alone (the paper's x + dt B a_k) puts w half a period ahead of the
/// truth: a bias that the omega^2 rows turn into a theta error on fast motions (FILTER.md).
/// P = Phi P Phi^T + Q with Phi = I + A dt (eqs. 16, 17).
template <class P, int N>
JA_FORCE_INLINE void TimeUpdate(const Settings<P, N>& c, typename P::Omega h0_a,
                                typename P::Omega h0_b, typename P::Omega h1_a,
                                typename P::Omega h1_b, FilterState<P>& st) {
  using Angle = typename P::Angle;
  using Cov = typename P::Cov;
  using Omega = typename P::Omega;
  Eigen::Matrix<Cov, 3, 3>& p = st.p;
  const Omega dh0 = h0_a - h0_b;
  Sum<Angle, typename P::Time, Omega> dtheta;
  dtheta.Add(c.dt, st.omega(0) - st.omega(1));
  dtheta.Add(c.dt_third, dh0 + dh0 + (h1_a - h1_b));
  st.theta = detail::WrapAngle(st.theta + dtheta.Result(), c.pi, c.two_pi);
  st.omega(0) = st.omega(0) + (h0_a + h1_a);
  st.omega(1) = st.omega(1) + (h0_b + h1_b);
  // P = Phi P Phi^T + Q with w = P (e0 - e1) (eqs. 16, 17).
  // w0 - w1 = P00 - P01 - P10 + P11 reaches 2 at P = I: formed as dt w0 - dt w1.
  const Cov w0 = p(0, 0) - p(0, 1), w1 = p(1, 0) - p(1, 1), w2 = p(2, 0) - p(2, 1);
  const Cov dt_w0 = Mul<Cov>(c.dt, w0), dt_w1 = Mul<Cov>(c.dt, w1);  // each used twice
  const Cov dt_dw = dt_w0 - dt_w1;
  Sum<Cov, typename P::Time, Cov> a22;  // P22 + dt (2 w2 + dt (w0 - w1))
  a22.AddValue(p(2, 2));
  a22.Add(c.dt, w2);
  a22.Add(c.dt, w2);
  a22.Add(c.dt, dt_dw);
  const Cov p22 = a22.Result();
  const Cov p02 = p(0, 2) + dt_w0;
  const Cov p12 = p(1, 2) + dt_w1;
  p(2, 2) = p22;
  p(0, 2) = p02;
  p(2, 0) = p02;
  p(1, 2) = p12;
  p(2, 1) = p12;
  p(0, 0) = p(0, 0) + c.q_a;
  p(1, 1) = p(1, 1) + c.q_b;
}

/// The time updates of `missed` periods the loop skipped (Step's `periods` - 1), out of line:
/// alpha held at the previous readings' (no reading in between), the last period (Step's own)
/// then goes from it to this step's.
template <class P, int N>
JA_NOINLINE void PredictMissedPeriods(const Settings<P, N>& c, FilterState<P>& st, uint8_t missed) {
  const typename P::Omega h_a = st.half_dw[0], h_b = st.half_dw[1];
  for (; missed != 0; --missed) TimeUpdate(c, h_a, h_b, h_a, h_b, st);
}

/// The omega^2 rows' first update after the hold as a measurement of w_a + w_b (Step, step 4).
/// Held back, the rows leave w_a and w_b to theta's motion, which fixes their difference
/// d = w_a - w_b but not their sum: from w = 0, P = diag(p, p) the filter splits d evenly (a
/// clamped link a turning at -d/2 while link b turns at d/2), and the rows linearised there
/// (H = 2w, flat where the truth is near 0) pull w towards the truth slowly, theta off
/// meanwhile. The readings give the magnitudes r_j = sqrt(G_w2 a_j): the sign choices
/// (+-r_a, +-r_b) whose difference matches d within 2 sigma of the best are plausible
/// (sigma^2 = var d + var r_a + var r_b, var r = r_jj / (4 max(G_w2 a, sqrt(r_jj)))), and the
/// plausible one whose sum is nearest the prior's is measured, with variance var r_a + var r_b,
/// in place of the rows (the same readings: their information used once). Only when theta's
/// motion has fixed d better than the readings fix the magnitudes (var d <= var r: the rows'
/// noise is small against the motion, as on the gravity rigs); else false, and the rows update
/// as in every later step. Once per filter start (~4 000 AVR cycles with the update).
template <class P, int N>
JA_NOINLINE bool ReleaseSum(const Settings<P, N>& c, const FilterState<P>& st,
                            typename P::Accel z_a, typename P::Accel z_b, typename P::Omega& sum_z,
                            typename P::Noise& sum_var) {
  using Noise = typename P::Noise;
  using Omega = typename P::Omega;
  using Inverse = typename P::Inverse;
  const Noise p01 = Cast<Noise>(st.p(0, 1));
  const Noise var_d = Cast<Noise>(st.p(0, 0)) + Cast<Noise>(st.p(1, 1)) - p01 - p01;
  Sum<Noise, Noise, Inverse> var_r_acc;
  var_r_acc.Add(c.r11_quarter, Recip<Inverse>(z_a < c.z_floor_a ? c.z_floor_a : z_a));
  var_r_acc.Add(c.r22_quarter, Recip<Inverse>(z_b < c.z_floor_b ? c.z_floor_b : z_b));
  const Noise var_r = var_r_acc.Result();
  if (var_d > var_r) return false;
  const Omega r_a = Sqrt<Omega>(z_a), r_b = Sqrt<Omega>(z_b);
  const Omega d = st.omega(0) - st.omega(1), prior_sum = st.omega(0) + st.omega(1);
  Omega miss[4], sum[4];
  Omega best_miss = Omega(0);
  for (uint8_t k = 0; k < 4; ++k) {  // (+,+), (+,-), (-,+), (-,-)
    const Omega ta = (k & 2u) ? -r_a : r_a, tb = (k & 1u) ? -r_b : r_b;
    const Omega diff = ta - tb - d;
    miss[k] = diff < Omega(0) ? -diff : diff;
    sum[k] = ta + tb;
    if (k == 0 || miss[k] < best_miss) best_miss = miss[k];
  }
  const Omega sigma = Sqrt<Omega>(var_d + var_r);
  const Omega limit = best_miss + sigma + sigma;
  bool found = false;
  Omega nearest = Omega(0);
  for (uint8_t k = 0; k < 4; ++k) {  // the plausible sum nearest the prior's (ties: the first)
    if (limit < miss[k]) continue;
    const Omega gap = sum[k] - prior_sum;
    const Omega far = gap < Omega(0) ? -gap : gap;
    if (!found || far < nearest) {
      nearest = far;
      sum_z = sum[k];
      found = true;
    }
  }
  sum_var = var_r;
  return found;
}

/// Initialisation (the first step, and after Reset()): w = 0, P = diag(p_omega0, p_omega0,
/// P_theta0); theta = the analytical estimate atan2(cross, dot) (eq. 12) with P_theta0 =
/// kThetaVariance0 when |z^a| |u| >= kInitMinProduct, else theta = 0, P_theta0 = 1 (eq. 12 is
/// meaningless without joint acceleration). The omega^2 rows are held back from here. Out of
/// line: once per start, and Step's every other step is faster without it inline (its frame
/// smaller: measured 0.1 % fixed, 0.3 % float, 2.6 KB less flash).
template <class P, int N>
JA_NOINLINE void Initialise(const Settings<P, N>& c, const typename P::Accel* za,
                            const typename P::Accel* u, FilterState<P>& st) {
  using Accel = typename P::Accel;
  using Cov = typename P::Cov;
  Eigen::Matrix<Cov, 3, 3>& p = st.p;
  Accel cross, dot;
  AnalyticalCrossDot<P>(za, u, cross, dot);
  // |za|^2 |u|^2 = cross^2 + dot^2: trust eq. 12 when it is at least kInitMinProduct^2.
  Sum<Accel, Accel, Accel> mag;
  mag.Add(cross, cross);
  mag.Add(dot, dot);
  const bool ok = !(mag.Result() < c.init_min_product2);
  st.omega.setConstant(typename P::Omega(0));
  st.theta = ok ? Atan2To<typename P::Angle>(cross, dot) : typename P::Angle(0);
  p.setConstant(Cov(0));
  p(0, 0) = c.p_omega0;
  p(1, 1) = c.p_omega0;
  p(2, 2) = ok ? c.p_theta0 : c.p_one;
  st.initialised = true;
  st.omega2_rows_on = false;
}

/// Step 1, the time update (eqs. 10, 13, 16, 17) over `periods` sample periods: the half
/// increments h = (dt / 2) G_alpha a of these readings, one dot product per link ((dt / 2) G_alpha
/// from Configure: no rounding of G_alpha a first) for all the periods; the missed periods with
/// alpha held at the previous readings' (out of line: the common step has none), then this one
/// from the previous readings' alpha to these (TimeUpdate). The first step has no earlier
/// readings: alpha is constant over it.
template <class P, int N>
JA_FORCE_INLINE void Predict(const Settings<P, N>& c,
                             const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_a,
                             const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_b, bool first,
                             uint8_t periods, FilterState<P>& st) {
  const typename P::Omega h_a = LinkOmegaIncrement(c.a, acc_a);
  const typename P::Omega h_b = LinkOmegaIncrement(c.b, acc_b);
  if (first) {
    st.half_dw[0] = h_a;
    st.half_dw[1] = h_b;
  }
  if (periods > 1) PredictMissedPeriods(c, st, periods - 1);
  TimeUpdate(c, st.half_dw[0], st.half_dw[1], h_a, h_b, st);
  st.half_dw[0] = h_a;
  st.half_dw[1] = h_b;
}

// The steps below hand their results to the caller's locals through reference parameters, not in
// structs: inlined, each local is a value in registers, while avr-gcc 5.4 left most fields of a
// struct of Fixed values in the stack frame (measured: +2.7 % cycles a step).

/// Step 2, the measurement at x^- (eqs. 11, 14, 15): z = [G_w2^a a^a, G_w2^b a^b, F^a a^a],
/// h(x) = [w_a^2, w_b^2, R(theta) u] with u = F^b a^b; y = z - h(x^-), sin and cos of theta^-, and
/// H's theta entries of rows 3 and 4, R'(theta) u = [h4, -h3] (its other non-zeros are 2 w_a and
/// 2 w_b of rows 1 and 2). za, u: F row 0, F row 1 and G_w2 times each link's readings
/// (LinkRows).
template <class P>
JA_FORCE_INLINE void Measure(const FilterState<P>& st, const typename P::Accel* za,
                             const typename P::Accel* u, typename P::Angle& sn,
                             typename P::Angle& cs, typename P::Accel& y1, typename P::Accel& y2,
                             typename P::Accel& y3, typename P::Accel& y4, typename P::Row& j3,
                             typename P::Row& j4) {
  using Accel = typename P::Accel;
  using Row = typename P::Row;
  SinCos(st.theta, sn, cs);
  Sum<Accel, typename P::Angle, Accel> h3_acc, h4_acc;  // R(theta) u
  h3_acc.Add(cs, u[0]);
  h3_acc.Add(sn, u[1]);
  h4_acc.Add(cs, u[1]);
  h4_acc.Subtract(sn, u[0]);
  const Accel h3 = h3_acc.Result(), h4 = h4_acc.Result();
  j3 = Cast<Row>(h4);
  j4 = Cast<Row>(-h3);
  y1 = za[2] - Mul<Accel>(st.omega(0), st.omega(0));  // G_w2^a a^a - w_a^2
  y2 = u[2] - Mul<Accel>(st.omega(1), st.omega(1));
  y3 = za[0] - h3;
  y4 = za[1] - h4;
}

/// Step 2, the measurement noise R_k = V Q^ V^T (eq. 18) where it depends on theta: the z3, z4
/// block R33 = M_a + R M_b R^T (r33, r34, r44) and cov(z2, z34) = -R c_b (r23, r24); cov(z1, z34)
/// = r13 and cov(z1, z2) = 0 are constants. For the symmetric M_b,
/// R M_b R^T = mean I + [[e, f], [f, -e]] (double angle, 6 products instead of 14):
///   e = dif cos 2t + m_b01 sin 2t,  f = m_b01 cos 2t - dif sin 2t,
///   cos 2t = c^2 - s^2,  sin 2t = 2 s c.
template <class P, int N>
JA_FORCE_INLINE void MeasurementNoise(const Settings<P, N>& c, typename P::Angle sn,
                                      typename P::Angle cs, typename P::Noise& r33,
                                      typename P::Noise& r34, typename P::Noise& r44,
                                      typename P::Noise& r23, typename P::Noise& r24) {
  using Angle = typename P::Angle;
  using Noise = typename P::Noise;
  // m_b01 = 0 and c_b1 = 0 for an array along its link's axis (F's rows then have disjoint
  // non-zeros), and dif = 0 too when its x and y noise are equal (F's rows then have equal
  // norms): those terms are skipped, exactly (both builds). With m_b01 = dif = 0
  // (decorrelation_fixed) e = 0 and R34 = m_a01: no double angle at all.
  const bool cb1 = !(c.c_b[1] == Noise(0));
  if (c.decorrelation_fixed) {
    r33 = c.r33_0;
    r44 = c.r44_0;
    r34 = c.m_a[1];
  } else {
    Sum<Angle, Angle, Angle> c2_acc;
    c2_acc.Add(cs, cs);
    c2_acc.Subtract(sn, sn);
    const Angle c2 = c2_acc.Result();
    const Angle sc = Mul<Angle>(sn, cs);
    const Angle s2 = sc + sc;
    const bool mb01 = !(c.m_b[1] == Noise(0));
    const bool dif = !(c.mb_dif == Noise(0));
    Sum<Noise, Noise, Angle> e_acc, f_acc;
    if (dif) e_acc.Add(c.mb_dif, c2);
    if (mb01) e_acc.Add(c.m_b[1], s2);
    f_acc.AddValue(c.m_a[1]);
    if (mb01) f_acc.Add(c.m_b[1], c2);
    if (dif) f_acc.Subtract(c.mb_dif, s2);
    const Noise e = e_acc.Result();
    r33 = c.r33_0 + e;
    r44 = c.r44_0 - e;
    r34 = f_acc.Result();
  }
  Sum<Noise, Angle, Noise> b23, b24;
  b23.Subtract(cs, c.c_b[0]);
  if (cb1) b23.Subtract(sn, c.c_b[1]);
  if (cb1) b24.Subtract(cs, c.c_b[1]);
  b24.Add(sn, c.c_b[0]);
  r23 = b23.Result();
  r24 = b24.Result();
}

/// Step 3, the decorrelation R_k = L D L^T (Gram-Schmidt on the measurement noise) in the order
/// (z3, z4, z1, z2): y~ = L^-1 y, H~ = L^-1 H, which keeps H~ sparse. The theta-independent part
/// (DecorrelateFixedPart) comes from Configure when R33, R34, R44 are constant, else it is
/// computed here; then the theta-dependent rest (l30, l31, l32, D3 and the rows of y~, H~).
/// In: y, H's rows 3 and 4 (j3, j4: Measure), R_k's varying blocks (MeasurementNoise). Out, by
/// row (z3 itself is y3, j3 with noise D0 = R33): rho = D0 / D1, the weight of z~4 against z3 in
/// the angle rows' update; z~4 = y~ yt1, H~ (0, 0, ht1); z~1 = yt2, (ht2_0, 0, ht2_2), noise d2;
/// z~2 = yt3, (ht3_0, ht3_1, ht3_2), noise d3.
template <class P, int N>
JA_FORCE_INLINE void Decorrelate(
    const Settings<P, N>& c, const FilterState<P>& st, typename P::Accel y1, typename P::Accel y2,
    typename P::Accel y3, typename P::Accel y4, typename P::Row j3, typename P::Row j4,
    typename P::Noise r33, typename P::Noise r34, typename P::Noise r44, typename P::Noise r23,
    typename P::Noise r24, typename P::Noise& rho, typename P::Accel& yt1, typename P::Row& ht1,
    typename P::Noise& d2, typename P::Accel& yt2, typename P::Row& ht2_0, typename P::Row& ht2_2,
    typename P::Noise& d3, typename P::Accel& yt3, typename P::Row& ht3_0, typename P::Row& ht3_1,
    typename P::Row& ht3_2) {
  using Accel = typename P::Accel;
  using Factor = typename P::Factor;  // the factors l of L (16 bits in FixedPolicy)
  using Inverse = typename P::Inverse;
  using Noise = typename P::Noise;
  using Row = typename P::Row;
  const Noise r13 = c.r13[0], r14 = c.r13[1];
  Inverse i0, i1, i2;
  Factor l10, l20, l21;
  Noise r14t, r24t = r24;
  yt1 = y4;
  ht1 = j4;
  if (c.decorrelation_fixed) {
    i0 = c.decorrelation.i0;
    i1 = c.decorrelation.i1;
    i2 = c.decorrelation.i2;
    l10 = c.decorrelation.l10;
    l20 = c.decorrelation.l20;
    l21 = c.decorrelation.l21;
    d2 = c.decorrelation.d2;
    r14t = c.decorrelation.r14t;
    rho = c.decorrelation.rho;
  } else {
    DecorrelateFixedPart<P>(r33, r34, r44, r13, r14, c.r11, i0, i1, i2, l10, l20, l21, r14t, d2,
                            rho);
  }
  if (!(l10 == Factor(0))) {
    Sum<Noise, Factor, Noise> e;
    e.AddValue(r24);
    e.Subtract(l10, r23);
    r24t = e.Result();
    Sum<Accel, Factor, Accel> y;
    y.AddValue(y4);
    y.Subtract(l10, y3);
    yt1 = y.Result();
    Sum<Row, Factor, Row> h;
    h.AddValue(j4);
    h.Subtract(l10, j3);
    ht1 = h.Result();
  }
  const bool has_l21 = !(l21 == Factor(0));
  Noise r21t;
  {
    Sum<Noise, Factor, Noise> b;
    b.Subtract(l20, r23);
    if (has_l21) b.Subtract(l21, r24t);
    r21t = b.Result();
    Sum<Accel, Factor, Accel> y;
    y.AddValue(y1);
    y.Subtract(l20, y3);
    if (has_l21) y.Subtract(l21, yt1);
    yt2 = y.Result();
    Sum<Row, Factor, Row> h;
    h.Subtract(l20, j3);
    if (has_l21) h.Subtract(l21, ht1);
    ht2_2 = h.Result();
  }
  ht2_0 = Cast<Row>(st.omega(0) + st.omega(0));
  const Factor l30 = Mul<Factor>(r23, i0), l31 = Mul<Factor>(r24t, i1);
  const Factor l32 = Mul<Factor>(r21t, i2);
  {
    Sum<Noise, Factor, Noise> a;
    a.AddValue(c.r22);
    a.Subtract(l30, r23);
    a.Subtract(l31, r24t);
    a.Subtract(l32, r21t);
    d3 = a.Result();
    Sum<Accel, Factor, Accel> y;
    y.AddValue(y2);
    y.Subtract(l30, y3);
    y.Subtract(l31, yt1);
    y.Subtract(l32, yt2);
    yt3 = y.Result();
    Sum<Row, Factor, Row> h;
    h.Subtract(l30, j3);
    h.Subtract(l31, ht1);
    h.Subtract(l32, ht2_2);
    ht3_2 = h.Result();
  }
  ht3_0 = -Mul<Row>(l32, ht2_0);
  ht3_1 = Cast<Row>(st.omega(1) + st.omega(1));
}

/// Step 4, the update by one decorrelated row z~m = (h0, h1, h2) with noise d: its innovation at
/// the state the earlier rows left, y~_m - h~_m (x - x^-) (Innovation; x^- = (w0m, w1m, thm),
/// the state before the first update), then the scalar update (ScalarUpdate). Returns the
/// innovation used.
template <bool kH0, bool kH1, class P>
JA_FORCE_INLINE typename P::Accel RowUpdate(FilterState<P>& st, typename P::Noise d,
                                            typename P::Accel y, typename P::Row h2,
                                            typename P::Row h1, typename P::Row h0,
                                            typename P::Omega w0m, typename P::Omega w1m,
                                            typename P::Angle thm) {
  const typename P::Accel nu = Innovation<kH0, kH1>(y, h2, h1, h0, st, w0m, w1m, thm);
  ScalarUpdate<kH0, kH1>(st, d, nu, h2, h1, h0);
  return nu;
}

/// Step 0: the readings at the row's time. A multiplexed board reads its sensors one after
/// another, sensor i tau_i after the row's time t_k (docs/as-built.md); to first order in tau_i,
///   a_i(t_k) ~= a_i[k] - (tau_i / dt) (a_i[k] - a_i[k-1])
/// (the slope over the last period, one multiply-add per reading; lag = tau_i / dt, Configure),
/// for the readings whose lag is not 0 (bit j of `mask`); the others are copied. `apply` false
/// (the filter's first step, whose a_i[k-1] is not known, or a step over several periods, whose
/// readings are held): the readings as read. Either way those readings are kept for the next.
template <class P, int N>
JA_FORCE_INLINE void AlignReadings(const typename P::Lag* lag, uint8_t mask, bool apply,
                                   const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc,
                                   typename P::Accel* previous,
                                   Eigen::Matrix<typename P::Accel, 2 * N, 1>& out) {
  using Accel = typename P::Accel;
  out = acc;
  for (int j = 0; j < 2 * N; ++j, mask = static_cast<uint8_t>(mask >> 1)) {
    if (!(mask & 1u)) continue;
    const Accel now = acc(j);
    if (apply) out(j) = now - Mul<Accel>(now - previous[j], lag[j]);
    previous[j] = now;
  }
}

/// Step 4, the omega^2 rows' first update when ReleaseSum measured w_a + w_b in their place:
/// h = (1, 1, 0), y = sum - (w_a + w_b) at the state the angle rows left, variance sum_var.
/// Returns y.
template <class P>
JA_FORCE_INLINE typename P::Accel SumUpdate(FilterState<P>& st, typename P::Omega sum_z,
                                            typename P::Noise sum_var) {
  using Row = typename P::Row;
  const Row zero(0), one(1);
  const typename P::Accel y = Cast<typename P::Accel>(sum_z - (st.omega(0) + st.omega(1)));
  ScalarUpdate<true, true>(st, sum_var, y, zero, one, one);
  return y;
}

/// Step 5, the bookkeeping: theta wrapped to (-pi, pi]; the health: the four decorrelated
/// innovations (y3, y~4 at x^-, then those of z~1, z~2), the step's saturations, the sample
/// periods (the omega^2 hold and the start-up are times also when the loop overruns).
template <class P, int N>
JA_FORCE_INLINE void FinishStep(const Settings<P, N>& c, typename P::Accel y3,
                                typename P::Accel yt1, typename P::Accel yc2, typename P::Accel yc3,
                                uint16_t saturations_before, uint8_t periods, FilterState<P>& st) {
  st.theta = WrapAngle(st.theta, c.pi, c.two_pi);
  st.health.innovation[0] = y3;
  st.health.innovation[1] = yt1;
  st.health.innovation[2] = yc2;
  st.health.innovation[3] = yc3;
  st.health.saturations =
      static_cast<uint16_t>(st.health.saturations + (SaturationCount() - saturations_before));
  st.health.steps += periods;
}

/// Steps 1-5 of Step on readings at the row's time.
template <class P, int N>
JA_NOINLINE void StepAtRowTime(const Settings<P, N>& c,
                               const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_a,
                               const Eigen::Matrix<typename P::Accel, 2 * N, 1>& acc_b,
                               FilterState<P>& st, uint8_t periods) {
  using Accel = typename P::Accel;
  using Angle = typename P::Angle;
  using Noise = typename P::Noise;
  using Omega = typename P::Omega;
  using Row = typename P::Row;
  const uint16_t saturations_before = SaturationCount();

  // Joint accelerations z^a = F^a a^a, u = F^b a^b (eq. 8), kept for the analytical estimate
  // (eq. 12, AnalyticalAngleOf). One SparseRows call per link: F row 0, F row 1 (z^a, u) and
  // G_w2 a (the omega^2 rows, step 2).
  Accel za[3], u[3];
  detail::LinkRows<3>(c.a, acc_a, za);
  detail::LinkRows<3>(c.b, acc_b, u);
  for (int i = 0; i < 2; ++i) {
    st.analytical_za[i] = za[i];
    st.analytical_u[i] = u[i];
  }
  const bool first = !st.initialised;
  if (first) {
    detail::Initialise(c, za, u, st);
    periods = 1;
  }
  if (periods == 0) periods = 1;
  if (periods > kMaxStepPeriods) periods = kMaxStepPeriods;

  JA_STEP_MARK(20);
  // 1. Time update (eqs. 10, 13, 16, 17), once per sample period since the last step.
  detail::Predict(c, acc_a, acc_b, first, periods, st);

  JA_STEP_MARK(21);
  // 2. Measurement at x^- (eqs. 11, 14, 15). In the omega^2 rows' first step after the hold a
  // measurement of w_a + w_b may take their place (ReleaseSum).
  const bool omega2_rows = st.health.steps >= c.hold_steps;
  bool by_sum = false;
  Omega sum_z(0);
  Noise sum_var(0);
  if (omega2_rows && !st.omega2_rows_on) {
    by_sum = detail::ReleaseSum(c, st, za[2], u[2], sum_z, sum_var);
    st.omega2_rows_on = true;
  }
  Angle sn, cs;
  Accel y1, y2, y3, y4;
  Row j3, j4;
  detail::Measure(st, za, u, sn, cs, y1, y2, y3, y4, j3, j4);
  JA_STEP_MARK(22);
  // Its noise R_k (eq. 18).
  Noise r33, r34, r44, r23, r24;
  detail::MeasurementNoise(c, sn, cs, r33, r34, r44, r23, r24);

  JA_STEP_MARK(23);
  // 3. Decorrelation in the order (z3, z4, z1, z2).
  Noise rho, d2, d3;
  Accel yt1, yt2, yt3;
  Row ht1, ht2_0, ht2_2, ht3_0, ht3_1, ht3_2;
  detail::Decorrelate(c, st, y1, y2, y3, y4, j3, j4, r33, r34, r44, r23, r24, rho, yt1, ht1, d2,
                      yt2, ht2_0, ht2_2, d3, yt3, ht3_0, ht3_1, ht3_2);

  JA_STEP_MARK(24);
  // 4. Sequential updates, all linearised at x^-: the two angle rows (z3, z~4) as one
  // (AngleRowsUpdate), then the rows z~1, z~2 one at a time (RowUpdate), or in their first step
  // after the hold the sum of w_a and w_b in their place (SumUpdate). Each row's innovation is
  // taken at the state the earlier rows left: then the updates are the batch EKF update
  // K = P^- H^T (H P^- H^T + R)^-1, P = (I - K H) P^- exactly (with y~_m alone they were not:
  // later rows counted part of the earlier rows' correction twice; measured 0.1-0.5 % above the
  // `ekf`'s steady RMS on 3 scenarios).
  const Row zero(0);
  const Omega w0m = st.omega(0), w1m = st.omega(1);
  const Angle thm = st.theta;
  Accel yc2 = yt2, yc3 = yt3;  // the innovations used (y~ at x^- for rows held back)
  const Noise d0 = r33;
  detail::AngleRowsUpdate(st, d0, rho, y3, j3, yt1, ht1);
  if (by_sum) {
    yc2 = detail::SumUpdate(st, sum_z, sum_var);
  } else if (omega2_rows) {
    yc2 = detail::RowUpdate<true, false>(st, d2, yt2, ht2_2, zero, ht2_0, w0m, w1m, thm);
    yc3 = detail::RowUpdate<true, true>(st, d3, yt3, ht3_2, ht3_1, ht3_0, w0m, w1m, thm);
  }

  JA_STEP_MARK(25);
  // 5. Wrap, health.
  detail::FinishStep(c, y3, yt1, yc2, yc3, saturations_before, periods, st);
}

}  // namespace detail

/// One filter step with this sample's link-frame readings (x, y of each sensor, m/s^2): the
/// steps of FILTER.md "One step (`Step`)", each a function above.
/// periods: sample periods since the previous step (1 on schedule; more when the loop missed
/// its deadlines, APP.md "Timing"): the time update runs that many times with these readings,
/// the model's dt grid kept, before the one measurement update. Clamped to 1..kMaxStepPeriods;
/// the filter's first step (its initialisation) takes 1.
template <class P, int N>
void Step(const Settings<P, N>& c, const Eigen::Matrix<typename P::Accel, 2 * N, 1>& read_a,
          const Eigen::Matrix<typename P::Accel, 2 * N, 1>& read_b, FilterState<P>& st,
          uint8_t periods = 1) {
  if ((c.read_lag_mask[0] | c.read_lag_mask[1]) == 0) {  // all read at once: as read
    detail::StepAtRowTime(c, read_a, read_b, st, periods);
    return;
  }
  // 0. The readings at the row's time (AlignReadings).
  Eigen::Matrix<typename P::Accel, 2 * N, 1> acc_a, acc_b;
  const bool apply = st.initialised && periods <= 1;
  detail::AlignReadings<P, N>(c.read_lag[0], c.read_lag_mask[0], apply, read_a, st.previous[0],
                              acc_a);
  detail::AlignReadings<P, N>(c.read_lag[1], c.read_lag_mask[1], apply, read_b, st.previous[1],
                              acc_b);
  detail::StepAtRowTime(c, acc_a, acc_b, st, periods);
}

}  // namespace core
}  // namespace ja
