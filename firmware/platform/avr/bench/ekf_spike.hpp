// The numeric spike of the paper's EKF (Woods & Vikas; docs/design.md §3): 3 states
// x = [w_a, w_b, theta_ab], 4 measurements, two 2-axis sensors per link. It exists to measure
// what a filter step costs on the ATmega2560 (firmware/core/NUMERICS.md, measured by
// bench_numerics.cpp beside it), not to be the shipped filter (core/joint_filter.hpp).
//
// Two forms of the same step, both templated over the scalar S (float or Fixed<F>):
//   StepDense:      textbook matrices: F P F^T + Q, H P H^T + V Q^ V^T, K = P H^T S^-1 with a
//                   general 4x4 inverse, P = (I - K H) P. The float instantiation is the baseline.
//   StepStructured: the same equations with the model's structure used:
//     - F = I + dt e3 (e1 - e2)^T:  F P F^T = P + dt (e3 w^T + w e3^T) + dt^2 (w0 - w1) e3 e3^T,
//       w = P (e1 - e2);  Q_k = dt^2 sigma^2 B B^T is diagonal (the links share no sensor) and
//       constant: two additions;
//     - H has 4 non-zeros: rows [2 w_a 0 0], [0 2 w_b 0], [0 0 j0], [0 0 j1], j = R'(theta) v_b;
//     - R_k = sigma^2 V V^T with its constant blocks precomputed at configuration; only the
//       rotated blocks change: R33 = M_a + R(theta) M_b R(theta)^T, R23 = -(R(theta) c_b)^T;
//     - S symmetric positive definite: LDL^T (4 reciprocals, no square root, no inverse),
//       K from three triangular solves, P = P - K (P H^T)^T on the upper triangle, mirrored.
#pragma once

#include "core/config.hpp"
#include "core/scalar_math.hpp"

namespace ja {
namespace core {
namespace spike {

/// Per-link array matrices (docs/design.md §3), derived from the sensor geometry.
template <class S>
struct LinkArray {
  Eigen::Matrix<S, 1, 4> g_omega2;  // G_w2 row: w^2 from the 4 accelerations, 1/s^2 per m/s^2
  Eigen::Matrix<S, 1, 4> g_alpha;   // G_alpha row: angular acceleration, 1/(m s^2) per m/s^2... 1/m
  Eigen::Matrix<S, 2, 4> f;         // F: joint acceleration (2) from the 4 accelerations
};

template <class S>
struct Config {
  LinkArray<S> a, b;
  S dt;      // s
  S sigma2;  // accelerometer noise variance, (m/s^2)^2
};

/// Constants derived once from Config for the structured step.
template <class S>
struct Derived {
  S q_a, q_b;                       // Q_k diagonal: dt^2 sigma^2 |G_alpha|^2
  S r11, r22;                       // sigma^2 |G_w2|^2
  Eigen::Matrix<S, 1, 2> r13;       // sigma^2 G_w2^a F_a^T
  Eigen::Matrix<S, 2, 1> c_b;       // sigma^2 F_b G_w2^b^T
  Eigen::Matrix<S, 2, 2> m_a, m_b;  // sigma^2 F F^T
};

template <class S>
struct State {
  Eigen::Matrix<S, 3, 1> x;  // [w_a rad/s, w_b rad/s, theta_ab rad]
  Eigen::Matrix<S, 3, 3> p;  // covariance
};

template <class S>
Derived<S> Derive(const Config<S>& c) {
  Derived<S> d;
  const S dt2s2 = c.dt * c.dt * c.sigma2;
  d.q_a = dt2s2 * c.a.g_alpha.squaredNorm();
  d.q_b = dt2s2 * c.b.g_alpha.squaredNorm();
  d.r11 = c.sigma2 * c.a.g_omega2.squaredNorm();
  d.r22 = c.sigma2 * c.b.g_omega2.squaredNorm();
  d.r13 = c.sigma2 * (c.a.g_omega2 * c.a.f.transpose());
  d.c_b = c.sigma2 * (c.b.f * c.b.g_omega2.transpose());
  d.m_a = c.sigma2 * (c.a.f * c.a.f.transpose());
  d.m_b = c.sigma2 * (c.b.f * c.b.f.transpose());
  return d;
}

/// Textbook EKF step with dense matrices. accel_a/accel_b: [s1x, s1y, s2x, s2y] in m/s^2.
template <class S>
void StepDense(const Config<S>& c, const Eigen::Matrix<S, 4, 1>& accel_a,
               const Eigen::Matrix<S, 4, 1>& accel_b, State<S>& st) {
  using M3 = Eigen::Matrix<S, 3, 3>;
  const S zero(0), one(1), two(2);
  // Time update: x = F x + dt B a,  F = I + A dt.
  M3 f = M3::Identity();
  f(2, 0) = c.dt;
  f(2, 1) = -c.dt;
  Eigen::Matrix<S, 3, 8> b = Eigen::Matrix<S, 3, 8>::Constant(zero);
  b.template block<1, 4>(0, 0) = c.a.g_alpha;
  b.template block<1, 4>(1, 4) = c.b.g_alpha;
  Eigen::Matrix<S, 8, 1> accel;
  accel << accel_a, accel_b;
  st.x = f * st.x + c.dt * (b * accel);
  const M3 q = (c.dt * c.dt * c.sigma2) * (b * b.transpose());
  st.p = f * st.p * f.transpose() + q;
  // Measurement: z = [G_w2a a_a, G_w2b a_b, F_a a_a],  h = [x1^2, x2^2, R(x3) F_b a_b].
  const Eigen::Matrix<S, 2, 1> v_b = c.b.f * accel_b;
  const S cs = Cos(st.x(2)), sn = Sin(st.x(2));
  Eigen::Matrix<S, 2, 2> rot, drot;
  rot << cs, sn, -sn, cs;
  drot << -sn, cs, -cs, -sn;
  Eigen::Matrix<S, 4, 1> z, h;
  z << c.a.g_omega2 * accel_a, c.b.g_omega2 * accel_b, c.a.f * accel_a;
  h << st.x(0) * st.x(0), st.x(1) * st.x(1), rot * v_b;
  Eigen::Matrix<S, 4, 3> hj = Eigen::Matrix<S, 4, 3>::Constant(zero);
  hj(0, 0) = two * st.x(0);
  hj(1, 1) = two * st.x(1);
  hj.template block<2, 1>(2, 2) = drot * v_b;
  Eigen::Matrix<S, 4, 8> v = Eigen::Matrix<S, 4, 8>::Constant(zero);
  v.template block<1, 4>(0, 0) = c.a.g_omega2;
  v.template block<1, 4>(1, 4) = c.b.g_omega2;
  v.template block<2, 4>(2, 0) = c.a.f;
  v.template block<2, 4>(2, 4) = -(rot * c.b.f);
  const Eigen::Matrix<S, 4, 4> r = c.sigma2 * (v * v.transpose());
  const Eigen::Matrix<S, 4, 4> s = hj * st.p * hj.transpose() + r;
  const Eigen::Matrix<S, 3, 4> k = st.p * hj.transpose() * s.inverse();
  st.x = st.x + k * (z - h);
  st.p = (M3::Identity() - k * hj) * st.p;
  (void)one;
}

/// The same step, structure exploited (see the file comment). Same inputs and state.
template <class S>
void StepStructured(const Config<S>& c, const Derived<S>& d, const Eigen::Matrix<S, 4, 1>& accel_a,
                    const Eigen::Matrix<S, 4, 1>& accel_b, State<S>& st) {
  const S two(2);
  Eigen::Matrix<S, 3, 1>& x = st.x;
  Eigen::Matrix<S, 3, 3>& p = st.p;
  // Time update: w_a += dt G_alpha^a a_a; w_b += dt G_alpha^b a_b; theta += dt (w_a - w_b).
  const S dw = x(0) - x(1);
  x(0) += c.dt * c.a.g_alpha.dot(accel_a.transpose());
  x(1) += c.dt * c.b.g_alpha.dot(accel_b.transpose());
  x(2) += c.dt * dw;
  // P = F P F^T + Q with w = P (e1 - e2).
  const Eigen::Matrix<S, 3, 1> w = p.col(0) - p.col(1);
  const S p22 = p(2, 2) + c.dt * (two * w(2) + c.dt * (w(0) - w(1)));
  const S p02 = p(0, 2) + c.dt * w(0);
  const S p12 = p(1, 2) + c.dt * w(1);
  p(0, 2) = p02;
  p(2, 0) = p02;
  p(1, 2) = p12;
  p(2, 1) = p12;
  p(2, 2) = p22;
  p(0, 0) += d.q_a;
  p(1, 1) += d.q_b;
  // Measurement model.
  const Eigen::Matrix<S, 2, 1> v_b = c.b.f * accel_b;
  const S cs = Cos(x(2)), sn = Sin(x(2));
  const S h2 = cs * v_b(0) + sn * v_b(1);  // R(theta) v_b
  const S h3 = cs * v_b(1) - sn * v_b(0);
  const S j0 = h3;  // R'(theta) v_b = [-s c; -c -s] v_b
  const S j1 = -h2;
  const S h00 = two * x(0), h11 = two * x(1);
  // Innovation y = z - h.
  const Eigen::Matrix<S, 2, 1> ja = c.a.f * accel_a;
  Eigen::Matrix<S, 4, 1> y;
  y(0) = c.a.g_omega2.dot(accel_a.transpose()) - x(0) * x(0);
  y(1) = c.b.g_omega2.dot(accel_b.transpose()) - x(1) * x(1);
  y(2) = ja(0) - h2;
  y(3) = ja(1) - h3;
  // PH^T (3x4): columns h00 P e1, h11 P e2, j0 P e3, j1 P e3.
  Eigen::Matrix<S, 3, 4> pht;
  pht.col(0) = h00 * p.col(0);
  pht.col(1) = h11 * p.col(1);
  pht.col(2) = j0 * p.col(2);
  pht.col(3) = j1 * p.col(2);
  // S = H P H^T + R (upper triangle; H rows pick rows of PH^T).
  Eigen::Matrix<S, 4, 4> sm;
  const S rc0 = cs * d.c_b(0) + sn * d.c_b(1);  // R(theta) c_b
  const S rc1 = cs * d.c_b(1) - sn * d.c_b(0);
  // R(theta) M_b R(theta)^T for symmetric M_b = [[a, b], [b, e]].
  const S mb_a = d.m_b(0, 0), mb_b = d.m_b(0, 1), mb_e = d.m_b(1, 1);
  const S t0 = cs * mb_a + sn * mb_b, t1 = cs * mb_b + sn * mb_e;  // row 0 of R M_b
  const S u0 = cs * mb_b - sn * mb_a, u1 = cs * mb_e - sn * mb_b;  // row 1 of R M_b
  sm(0, 0) = h00 * pht(0, 0) + d.r11;
  sm(0, 1) = h00 * pht(0, 1);
  sm(0, 2) = h00 * pht(0, 2) + d.r13(0);
  sm(0, 3) = h00 * pht(0, 3) + d.r13(1);
  sm(1, 1) = h11 * pht(1, 1) + d.r22;
  sm(1, 2) = h11 * pht(1, 2) - rc0;
  sm(1, 3) = h11 * pht(1, 3) - rc1;
  sm(2, 2) = j0 * pht(2, 2) + d.m_a(0, 0) + (t0 * cs + t1 * sn);
  sm(2, 3) = j0 * pht(2, 3) + d.m_a(0, 1) + (u0 * cs + u1 * sn);
  sm(3, 3) = j1 * pht(2, 3) + d.m_a(1, 1) + (u1 * cs - u0 * sn);
  // LDL^T of S: S = L D L^T, L unit lower (stored in sm's lower triangle), inv_d = 1/D.
  Eigen::Matrix<S, 4, 1> inv_d;
  const S one(1);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < i; ++j) {
      // L(i,j) = (S(j,i) - sum_{k<j} L(i,k) D(k) L(j,k)) / D(j); sm(i,k) holds L(i,k) D(k).
      S acc = sm(j, i);
      for (int k = 0; k < j; ++k) acc -= sm(i, k) * sm(j, k) * inv_d(k);
      sm(i, j) = acc;  // = L(i,j) D(j)
    }
    S dii = sm(i, i);
    for (int k = 0; k < i; ++k) dii -= sm(i, k) * sm(i, k) * inv_d(k);
    inv_d(i) = one / dii;
  }
  // K = PH^T S^-1: for each state row r solve S k_r = pht_r^T (S symmetric).
  Eigen::Matrix<S, 3, 4> k;
  for (int r = 0; r < 3; ++r) {
    Eigen::Matrix<S, 4, 1> t;
    for (int i = 0; i < 4; ++i) {  // L t = b  (L(i,k) = sm(i,k) inv_d(k))
      S acc = pht(r, i);
      for (int kk = 0; kk < i; ++kk) acc -= sm(i, kk) * inv_d(kk) * t(kk);
      t(i) = acc;
    }
    for (int i = 3; i >= 0; --i) {  // D L^T k = t
      S acc = t(i) * inv_d(i);
      for (int kk = i + 1; kk < 4; ++kk) acc -= sm(kk, i) * inv_d(i) * k(r, kk);
      k(r, i) = acc;
    }
  }
  // x += K y;  P -= K (P H^T)^T  (symmetric: upper triangle, mirrored).
  x += k * y;
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j) {
      const S v = p(i, j) - k.row(i).dot(pht.row(j));
      p(i, j) = v;
      p(j, i) = v;
    }
  }
}

/// StepStructured with every sum of products in an Accumulator: for Fixed, one rounding and one
/// saturation test per sum instead of per term; for float, the same arithmetic as StepStructured.
template <class S>
void StepStructuredMac(const Config<S>& c, const Derived<S>& d,
                       const Eigen::Matrix<S, 4, 1>& accel_a, const Eigen::Matrix<S, 4, 1>& accel_b,
                       State<S>& st) {
  const S two(2);
  // sum_j r(j) v(j) for a 1x4 row and a 4-vector.
  auto dot4 = [](const Eigen::Matrix<S, 1, 4>& r, const Eigen::Matrix<S, 4, 1>& v) {
    Accumulator<S> acc;
    for (int j = 0; j < 4; ++j) acc.Add(r(0, j), v(j));
    return acc.Result();
  };
  // F v for a 2x4 F.
  auto mul24 = [](const Eigen::Matrix<S, 2, 4>& f, const Eigen::Matrix<S, 4, 1>& v) {
    Eigen::Matrix<S, 2, 1> out;
    for (int i = 0; i < 2; ++i) {
      Accumulator<S> acc;
      for (int j = 0; j < 4; ++j) acc.Add(f(i, j), v(j));
      out(i) = acc.Result();
    }
    return out;
  };
  Eigen::Matrix<S, 3, 1>& x = st.x;
  Eigen::Matrix<S, 3, 3>& p = st.p;
  // Time update: w_a += dt G_alpha^a a_a; w_b += dt G_alpha^b a_b; theta += dt (w_a - w_b).
  const S dw = x(0) - x(1);
  x(0) += c.dt * dot4(c.a.g_alpha, accel_a);
  x(1) += c.dt * dot4(c.b.g_alpha, accel_b);
  x(2) += c.dt * dw;
  // P = F P F^T + Q with w = P (e1 - e2).
  const Eigen::Matrix<S, 3, 1> w = p.col(0) - p.col(1);
  const S p22 = p(2, 2) + c.dt * (two * w(2) + c.dt * (w(0) - w(1)));
  const S p02 = p(0, 2) + c.dt * w(0);
  const S p12 = p(1, 2) + c.dt * w(1);
  p(0, 2) = p02;
  p(2, 0) = p02;
  p(1, 2) = p12;
  p(2, 1) = p12;
  p(2, 2) = p22;
  p(0, 0) += d.q_a;
  p(1, 1) += d.q_b;
  // Measurement model.
  const Eigen::Matrix<S, 2, 1> v_b = mul24(c.b.f, accel_b);
  const S cs = Cos(x(2)), sn = Sin(x(2));
  const S h2 = cs * v_b(0) + sn * v_b(1);  // R(theta) v_b
  const S h3 = cs * v_b(1) - sn * v_b(0);
  const S j0 = h3;  // R'(theta) v_b = [-s c; -c -s] v_b
  const S j1 = -h2;
  const S h00 = two * x(0), h11 = two * x(1);
  // Innovation y = z - h.
  const Eigen::Matrix<S, 2, 1> ja = mul24(c.a.f, accel_a);
  Eigen::Matrix<S, 4, 1> y;
  {
    Accumulator<S> acc;
    for (int j = 0; j < 4; ++j) acc.Add(c.a.g_omega2(0, j), accel_a(j));
    acc.Subtract(x(0), x(0));
    y(0) = acc.Result();
  }
  {
    Accumulator<S> acc;
    for (int j = 0; j < 4; ++j) acc.Add(c.b.g_omega2(0, j), accel_b(j));
    acc.Subtract(x(1), x(1));
    y(1) = acc.Result();
  }
  y(2) = ja(0) - h2;
  y(3) = ja(1) - h3;
  // PH^T (3x4): columns h00 P e1, h11 P e2, j0 P e3, j1 P e3.
  Eigen::Matrix<S, 3, 4> pht;
  pht.col(0) = h00 * p.col(0);
  pht.col(1) = h11 * p.col(1);
  pht.col(2) = j0 * p.col(2);
  pht.col(3) = j1 * p.col(2);
  // S = H P H^T + R (upper triangle; H rows pick rows of PH^T).
  Eigen::Matrix<S, 4, 4> sm;
  const S rc0 = cs * d.c_b(0) + sn * d.c_b(1);  // R(theta) c_b
  const S rc1 = cs * d.c_b(1) - sn * d.c_b(0);
  // R(theta) M_b R(theta)^T for symmetric M_b = [[a, b], [b, e]].
  const S mb_a = d.m_b(0, 0), mb_b = d.m_b(0, 1), mb_e = d.m_b(1, 1);
  const S t0 = cs * mb_a + sn * mb_b, t1 = cs * mb_b + sn * mb_e;  // row 0 of R M_b
  const S u0 = cs * mb_b - sn * mb_a, u1 = cs * mb_e - sn * mb_b;  // row 1 of R M_b
  sm(0, 0) = h00 * pht(0, 0) + d.r11;
  sm(0, 1) = h00 * pht(0, 1);
  sm(0, 2) = h00 * pht(0, 2) + d.r13(0);
  sm(0, 3) = h00 * pht(0, 3) + d.r13(1);
  sm(1, 1) = h11 * pht(1, 1) + d.r22;
  sm(1, 2) = h11 * pht(1, 2) - rc0;
  sm(1, 3) = h11 * pht(1, 3) - rc1;
  sm(2, 2) = j0 * pht(2, 2) + d.m_a(0, 0) + (t0 * cs + t1 * sn);
  sm(2, 3) = j0 * pht(2, 3) + d.m_a(0, 1) + (u0 * cs + u1 * sn);
  sm(3, 3) = j1 * pht(2, 3) + d.m_a(1, 1) + (u1 * cs - u0 * sn);
  // LDL^T of S: S = L D L^T, L unit lower (stored in sm's lower triangle), inv_d = 1/D.
  Eigen::Matrix<S, 4, 1> inv_d;
  const S one(1);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < i; ++j) {
      // L(i,j) = (S(j,i) - sum_{k<j} L(i,k) D(k) L(j,k)) / D(j); sm(i,k) holds L(i,k) D(k).
      Accumulator<S> acc;
      acc.AddValue(sm(j, i));
      for (int k = 0; k < j; ++k) acc.Subtract(sm(i, k) * inv_d(k), sm(j, k));
      sm(i, j) = acc.Result();  // = L(i,j) D(j)
    }
    Accumulator<S> dii;
    dii.AddValue(sm(i, i));
    for (int k = 0; k < i; ++k) dii.Subtract(sm(i, k) * inv_d(k), sm(i, k));
    inv_d(i) = one / dii.Result();
  }
  // K = PH^T S^-1: for each state row r solve S k_r = pht_r^T (S symmetric).
  Eigen::Matrix<S, 3, 4> k;
  for (int r = 0; r < 3; ++r) {
    Eigen::Matrix<S, 4, 1> t;
    for (int i = 0; i < 4; ++i) {  // L t = b  (L(i,k) = sm(i,k) inv_d(k))
      Accumulator<S> acc;
      acc.AddValue(pht(r, i));
      for (int kk = 0; kk < i; ++kk) acc.Subtract(sm(i, kk) * inv_d(kk), t(kk));
      t(i) = acc.Result();
    }
    for (int i = 3; i >= 0; --i) {  // D L^T k = t
      Accumulator<S> acc;
      acc.Add(t(i), inv_d(i));
      for (int kk = i + 1; kk < 4; ++kk) acc.Subtract(sm(kk, i) * inv_d(i), k(r, kk));
      k(r, i) = acc.Result();
    }
  }
  // x += K y;  P -= K (P H^T)^T  (symmetric: upper triangle, mirrored).
  for (int i = 0; i < 3; ++i) {
    Accumulator<S> acc;
    acc.AddValue(x(i));
    for (int j = 0; j < 4; ++j) acc.Add(k(i, j), y(j));
    x(i) = acc.Result();
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j) {
      Accumulator<S> acc;
      acc.AddValue(p(i, j));
      for (int m = 0; m < 4; ++m) acc.Subtract(k(i, m), pht(j, m));
      const S v = acc.Result();
      p(i, j) = v;
      p(j, i) = v;
    }
  }
}

}  // namespace spike
}  // namespace core
}  // namespace ja
