// The numeric spike, measured: cycles of each arithmetic primitive and of the paper's EKF step
// (dense float, structured float, structured fixed point) on the ATmega2560 in simavr, with
// firmware/sim/avr_cycles. Also built for x86: lines "check NAME VALUE" print integer results of
// the fixed-point code, which must be identical on both (bit-exact parity), and "value NAME V"
// lines print float results scaled by 1e6 for information.
#include <stdint.h>

#include "bench_io.hpp"
#include "core/fixed_eigen.hpp"
#include "core/fixed_trig.hpp"
#include "ekf_spike.hpp"

namespace {

// The spike's single format: Q15.16 (range +-32768, lsb 1.5e-5). Q7.24 overflows 1/D of the
// innovation covariance (D ~ 0.004 -> 250 > 128); per-quantity formats are the next step.
using Q = ja::core::Fixed<16>;
using ja::core::spike::Config;
using ja::core::spike::Derived;
using ja::core::spike::State;

enum Region : uint8_t {
  kEmpty = 1,
  kFloatMul,
  kFloatAdd,
  kFloatDiv,
  kFloatSin,
  kFloatAtan2,
  kFloatSqrt,
  kInt32Mul,
  kInt64Mul,
  kNaiveQ16Mul,
  kFixedMul,
  kFixedAdd,
  kFixedDiv,
  kFixedSin,
  kFixedCos,
  kFixedAtan2,
  kFloatMat3Mul,
  kFixedMat3Mul,
  kEkfDenseFloat,
  kEkfStructFloat,
  kEkfStructFixed,
  kEkfMacFloat,
  kEkfMacFixed,
  kFixedMac4,
  kFloatMac4,
  kFixedDot4,
};

// Inputs through volatiles so the compiler cannot fold the measured operations.
volatile float vf_a = 1.2345f, vf_b = -0.98765f, vf_r;
volatile int32_t vi_a = 123456789L, vi_b = -98765L, vi_r;
volatile int64_t vl_a = 123456789LL, vl_b = -98765LL, vl_r;

// 32-bit LCG for test inputs (same sequence on every platform).
uint32_t g_lcg = 12345u;
int32_t NextRandom() {
  g_lcg = g_lcg * 1664525u + 1013904223u;
  return static_cast<int32_t>(g_lcg);
}

// FNV-1a over the raw values: one number that pins every bit of a sequence of results.
struct Hash {
  uint32_t h = 2166136261u;
  void Add(int32_t v) {
    for (int i = 0; i < 4; ++i) {
      h ^= static_cast<uint8_t>(static_cast<uint32_t>(v) >> (8 * i));
      h *= 16777619u;
    }
  }
};

void PrintCheck(const char* name, uint32_t v) {
  bench::Print("check ");
  bench::Print(name);
  bench::Print(" ");
  bench::PrintInt(static_cast<int32_t>(v >> 1));  // non-negative for PrintInt
  bench::Print("\n");
}

void PrintValue(const char* name, float v) {
  bench::Print("value ");
  bench::Print(name);
  bench::Print(" ");
  bench::PrintInt(static_cast<int32_t>(v * 1e6f));
  bench::Print("\n");
}

// Each primitive runs in its own small function (operands from pointers, result to a pointer),
// so the figures are not inflated by the bench's large stack frame: a region is call + load +
// operation + store + return, like docs/sensors.md §C2.
#define JA_BENCH_FN __attribute__((noinline))
JA_BENCH_FN void OpFloatMul(const float* a, const float* b, float* r) { *r = *a * *b; }
JA_BENCH_FN void OpFloatAdd(const float* a, const float* b, float* r) { *r = *a + *b; }
JA_BENCH_FN void OpFloatDiv(const float* a, const float* b, float* r) { *r = *a / *b; }
JA_BENCH_FN void OpFloatSin(const float* a, const float*, float* r) { *r = ja::core::Sin(*a); }
JA_BENCH_FN void OpFloatAtan2(const float* a, const float* b, float* r) {
  *r = ja::core::Atan2(*a, *b);
}
JA_BENCH_FN void OpFloatSqrt(const float* a, const float*, float* r) { *r = sqrtf(*a); }
JA_BENCH_FN void OpInt32Mul(const int32_t* a, const int32_t* b, int32_t* r) { *r = *a * *b; }
JA_BENCH_FN void OpNaiveQ16Mul(const int32_t* a, const int32_t* b, int32_t* r) {
  *r = static_cast<int32_t>((static_cast<int64_t>(*a) * *b) >> 16);
}
JA_BENCH_FN void OpInt64Mul(const int64_t* a, const int64_t* b, int64_t* r) { *r = *a * *b; }
JA_BENCH_FN void OpFixedMul(const Q* a, const Q* b, Q* r) { *r = *a * *b; }
JA_BENCH_FN void OpFixedAdd(const Q* a, const Q* b, Q* r) { *r = *a + *b; }
JA_BENCH_FN void OpFixedDiv(const Q* a, const Q* b, Q* r) { *r = *b / *a; }
JA_BENCH_FN void OpFixedSin(const Q* a, const Q*, Q* r) { *r = ja::core::Sin(*a); }
JA_BENCH_FN void OpFixedCos(const Q* a, const Q*, Q* r) { *r = ja::core::Cos(*a); }
JA_BENCH_FN void OpFixedAtan2(const Q* a, const Q* b, Q* r) { *r = ja::core::Atan2(*a, *b); }
// 4-term dot products: float, fixed with a rounding per product, fixed with one accumulator.
JA_BENCH_FN void OpFloatDot4(const float* a, const float* b, float* r) {
  float s = 0;
  for (int i = 0; i < 4; ++i) s += a[i] * b[i];
  *r = s;
}
JA_BENCH_FN void OpFixedDot4(const Q* a, const Q* b, Q* r) {
  Q s;
  for (int i = 0; i < 4; ++i) s += a[i] * b[i];
  *r = s;
}
JA_BENCH_FN void OpFixedMac4(const Q* a, const Q* b, Q* r) {
  ja::core::Accumulator<Q> acc;
  for (int i = 0; i < 4; ++i) acc.Add(a[i], b[i]);
  *r = acc.Result();
}

template <class T>
void Measure(uint8_t region, void (*op)(const T*, const T*, T*), const T* a, const T* b, T* r) {
  bench::Begin(region);
  op(a, b, r);
  bench::End();
}

void MeasurePrimitives() {
  float fa[4] = {vf_a, 0.5f, -0.25f, 2.0f}, fb[4] = {vf_b, 1.5f, 0.75f, -3.0f}, fr = 0;
  int32_t ia = vi_a, ib = vi_b, ir = 0;
  int64_t la = vl_a, lb = vl_b, lr = 0;
  Q qa[4] = {Q::FromRaw(vi_a >> 4), Q(0.5f), Q(-0.25f), Q(2.0f)};
  Q qb[4] = {Q::FromRaw(vi_b), Q(1.5f), Q(0.75f), Q(-3.0f)};
  Q qr;
  for (int rep = 0; rep < 4; ++rep) {
    bench::Begin(kEmpty);
    bench::End();
    Measure(kFloatMul, OpFloatMul, fa, fb, &fr);
    Measure(kFloatAdd, OpFloatAdd, fa, fb, &fr);
    Measure(kFloatDiv, OpFloatDiv, fa, fb, &fr);
    Measure(kFloatSin, OpFloatSin, fa, fb, &fr);
    Measure(kFloatAtan2, OpFloatAtan2, fa, fb, &fr);
    Measure(kFloatSqrt, OpFloatSqrt, fa, fb, &fr);
    Measure(kFloatMac4, OpFloatDot4, fa, fb, &fr);
    Measure(kInt32Mul, OpInt32Mul, &ia, &ib, &ir);
    Measure(kNaiveQ16Mul, OpNaiveQ16Mul, &ia, &ib, &ir);
    Measure(kInt64Mul, OpInt64Mul, &la, &lb, &lr);
    Measure(kFixedMul, OpFixedMul, qa, qb, &qr);
    Measure(kFixedAdd, OpFixedAdd, qa, qb, &qr);
    Measure(kFixedDiv, OpFixedDiv, qa, qb, &qr);
    Measure(kFixedSin, OpFixedSin, qa, qb, &qr);
    Measure(kFixedCos, OpFixedCos, qa, qb, &qr);
    Measure(kFixedAtan2, OpFixedAtan2, qa, qb, &qr);
    Measure(kFixedDot4, OpFixedDot4, qa, qb, &qr);
    Measure(kFixedMac4, OpFixedMac4, qa, qb, &qr);
  }
  vf_r = fr;
  vi_r = ir + qr.raw();
  vl_r = lr;
  // 3x3 matrix products through Eigen.
  Eigen::Matrix<float, 3, 3> fm, fp;
  Eigen::Matrix<Q, 3, 3> qm, qp;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      fm(i, j) = vf_a * static_cast<float>(i + 1) - static_cast<float>(j);
      qm(i, j) = Q::FromRaw(vi_b * (i + 1) - j);
    }
  }
  bench::Begin(kFloatMat3Mul);
  fp.noalias() = fm * fm.transpose();
  bench::End();
  bench::Begin(kFixedMat3Mul);
  qp.noalias() = qm * qm.transpose();
  bench::End();
  vf_r = fp(1, 2);
  vi_r = qp(1, 2).raw();
}

void CheckFixedPrimitives() {
  Hash mul, add, div, sincos, atan2;
  ja::core::SaturationCount() = 0;
  for (int i = 0; i < 200; ++i) {
    const Q a = Q::FromRaw(NextRandom() >> (i % 24));
    const Q b = Q::FromRaw(NextRandom() >> (i % 20));
    mul.Add((a * b).raw());
    add.Add((a + b).raw());
    add.Add((a - b).raw());
    div.Add((a / b).raw());
    const Q angle = Q::FromRaw(NextRandom() >> 5);  // +-64 rad
    sincos.Add(ja::core::Sin(angle).raw());
    sincos.Add(ja::core::Cos(angle).raw());
    atan2.Add(ja::core::Atan2(a, b).raw());
  }
  PrintCheck("fixed_mul", mul.h);
  PrintCheck("fixed_add", add.h);
  PrintCheck("fixed_div", div.h);
  PrintCheck("fixed_sincos", sincos.h);
  PrintCheck("fixed_atan2", atan2.h);
  PrintCheck("fixed_saturations", ja::core::SaturationCount());
}

// The spike's rig: link a joint at (0.30, 0), sensors (0.25, 0) and (0.05, 0.01); link b joint at
// (0, 0), sensors (0.05, 0) and (0.25, 0.01). G and F from docs/design.md §3 (numpy, pinv).
const float kArrays[2][4][4] = {{{-4.987531f, 0.2493766f, 4.987531f, -0.2493766f},
                                 {0.2493766f, 4.987531f, -0.2493766f, -4.987531f},
                                 {1.249377f, -0.01246883f, -0.2493766f, 0.01246883f},
                                 {0.01246883f, 1.249377f, -0.01246883f, -0.2493766f}},
                                {{4.987531f, 0.2493766f, -4.987531f, -0.2493766f},
                                 {0.2493766f, -4.987531f, -0.2493766f, 4.987531f},
                                 {1.249377f, 0.01246883f, -0.2493766f, -0.01246883f},
                                 {-0.01246883f, 1.249377f, 0.01246883f, -0.2493766f}}};
const float kSensors[2][2][2] = {{{0.25f, 0.0f}, {0.05f, 0.01f}}, {{0.05f, 0.0f}, {0.25f, 0.01f}}};
const float kJoints[2][2] = {{0.30f, 0.0f}, {0.0f, 0.0f}};
constexpr float kDt = 0.002f;      // s (500 Hz)
constexpr float kSigma = 0.0620f;  // m/s^2: 400 ug/sqrt(Hz) * g * sqrt(250 Hz)

template <class S>
Config<S> MakeConfig() {
  Config<S> c;
  ja::core::spike::LinkArray<S>* links[2] = {&c.a, &c.b};
  for (int l = 0; l < 2; ++l) {
    for (int j = 0; j < 4; ++j) {
      links[l]->g_omega2(0, j) = S(kArrays[l][0][j]);
      links[l]->g_alpha(0, j) = S(kArrays[l][1][j]);
      links[l]->f(0, j) = S(kArrays[l][2][j]);
      links[l]->f(1, j) = S(kArrays[l][3][j]);
    }
  }
  c.dt = S(kDt);
  c.sigma2 = S(kSigma * kSigma);
  return c;
}

template <class S>
State<S> MakeState() {
  State<S> s;
  s.x.setConstant(S(0));
  s.p.setConstant(S(0));
  for (int i = 0; i < 3; ++i) s.p(i, i) = S(1);
  return s;
}

// Synthetic motion: link a swings about its origin, theta_a = 0.6 sin(2 pi 1.5 t), link b about
// the joint with theta_ab = 0.4 + 0.5 sin(2 pi 1 t). Specific force in each link frame:
// a_i = a_J + D(r_i - r_J) [w^2, alpha], D(r) = [[-r1, -r2], [-r2, r1]], plus an LCG dither.
// Computed in Q16 fixed point so the inputs are bit-identical on AVR and x86; the float filters
// get the same values converted exactly.
using In = ja::core::Fixed<16>;
struct Inputs {
  In a[4], b[4];
};
Inputs MakeInputs(int k) {
  const In t = In::FromRaw(static_cast<int32_t>(k) * 131);  // k * 0.002 s (131/65536)
  const In wa(2.0f * 3.14159265f * 1.5f), wr(2.0f * 3.14159265f * 1.0f);
  const In omega_a = In(0.6f) * wa * ja::core::Cos(wa * t);
  const In alpha_a = -(In(0.6f) * wa * wa * ja::core::Sin(wa * t));
  const In theta_ab = In(0.4f) + In(0.5f) * ja::core::Sin(wr * t);
  const In omega_ab = In(0.5f) * wr * ja::core::Cos(wr * t);
  const In alpha_ab = -(In(0.5f) * wr * wr * ja::core::Sin(wr * t));
  const In omega_b = omega_a - omega_ab, alpha_b = alpha_a - alpha_ab;
  const In ya[2] = {omega_a * omega_a, alpha_a}, yb[2] = {omega_b * omega_b, alpha_b};
  // Joint acceleration in frame a (link a rotates about its origin), then in frame b = R^T v_a.
  const In rj0(kJoints[0][0]), rj1(kJoints[0][1]);
  const In ja0 = -(rj0 * ya[0]) - rj1 * ya[1], ja1 = -(rj1 * ya[0]) + rj0 * ya[1];
  const In c = ja::core::Cos(theta_ab), s = ja::core::Sin(theta_ab);
  const In jb0 = c * ja0 - s * ja1, jb1 = s * ja0 + c * ja1;
  Inputs in;
  for (int i = 0; i < 2; ++i) {
    const In r0(kSensors[0][i][0]), r1(kSensors[0][i][1]);
    in.a[2 * i] = -(r0 * ya[0]) - r1 * ya[1];
    in.a[2 * i + 1] = -(r1 * ya[0]) + r0 * ya[1];
    const In d0 = In(kSensors[1][i][0]) - In(kJoints[1][0]);
    const In d1 = In(kSensors[1][i][1]) - In(kJoints[1][1]);
    in.b[2 * i] = jb0 - d0 * yb[0] - d1 * yb[1];
    in.b[2 * i + 1] = jb1 - d1 * yb[0] + d0 * yb[1];
  }
  for (int i = 0; i < 4; ++i) {  // +-0.05 m/s^2 dither
    in.a[i] += In::FromRaw(NextRandom() >> 21);
    in.b[i] += In::FromRaw(NextRandom() >> 21);
  }
  return in;
}

template <class S>
S FromInput(In v);
template <>
float FromInput<float>(In v) {
  return v.ToFloat();
}
template <>
Q FromInput<Q>(In v) {
  return ja::core::ConvertFixed<Q::kFractionBits>(v);
}

template <class S>
void ToVectors(const Inputs& in, Eigen::Matrix<S, 4, 1>& a, Eigen::Matrix<S, 4, 1>& b) {
  for (int i = 0; i < 4; ++i) {
    a(i) = FromInput<S>(in.a[i]);
    b(i) = FromInput<S>(in.b[i]);
  }
}

constexpr int kDenseSteps = 12;
constexpr int kSteps = 150;

void MeasureEkf() {
  // Dense float: the textbook baseline (few steps: it is slow).
  {
    const Config<float> c = MakeConfig<float>();
    State<float> st = MakeState<float>();
    g_lcg = 777u;
    for (int k = 0; k < kDenseSteps; ++k) {
      Eigen::Matrix<float, 4, 1> a, b;
      ToVectors(MakeInputs(k), a, b);
      bench::Begin(kEkfDenseFloat);
      ja::core::spike::StepDense(c, a, b, st);
      bench::End();
    }
    PrintValue("dense_float_theta", st.x(2));
  }
  float theta_float = 0, omega_a_float = 0;
  {
    const Config<float> c = MakeConfig<float>();
    const Derived<float> d = ja::core::spike::Derive(c);
    State<float> st = MakeState<float>();
    g_lcg = 777u;
    for (int k = 0; k < kSteps; ++k) {
      Eigen::Matrix<float, 4, 1> a, b;
      ToVectors(MakeInputs(k), a, b);
      bench::Begin(kEkfStructFloat);
      ja::core::spike::StepStructured(c, d, a, b, st);
      bench::End();
      if (k == kDenseSteps - 1) PrintValue("structured_float_theta_at_dense_end", st.x(2));
    }
    theta_float = st.x(2);
    omega_a_float = st.x(0);
    PrintValue("structured_float_theta", theta_float);
    PrintValue("structured_float_omega_a", omega_a_float);
  }
  {
    const Config<Q> c = MakeConfig<Q>();
    const Derived<Q> d = ja::core::spike::Derive(c);
    State<Q> st = MakeState<Q>();
    g_lcg = 777u;
    Hash h;
    ja::core::SaturationCount() = 0;
    for (int k = 0; k < kSteps; ++k) {
      Eigen::Matrix<Q, 4, 1> a, b;
      ToVectors(MakeInputs(k), a, b);
      bench::Begin(kEkfStructFixed);
      ja::core::spike::StepStructured(c, d, a, b, st);
      bench::End();
      for (int i = 0; i < 3; ++i) h.Add(st.x(i).raw());
    }
    PrintCheck("ekf_fixed_states", h.h);
    PrintCheck("ekf_fixed_saturations", ja::core::SaturationCount());
    PrintValue("structured_fixed_theta", st.x(2).ToFloat());
    PrintValue("structured_fixed_omega_a", st.x(0).ToFloat());
    PrintValue("fixed_minus_float_theta", st.x(2).ToFloat() - theta_float);
    PrintValue("fixed_minus_float_omega_a", st.x(0).ToFloat() - omega_a_float);
  }
  // The same structured step with wide accumulators, float then fixed.
  {
    const Config<float> c = MakeConfig<float>();
    const Derived<float> d = ja::core::spike::Derive(c);
    State<float> st = MakeState<float>();
    g_lcg = 777u;
    for (int k = 0; k < kSteps; ++k) {
      Eigen::Matrix<float, 4, 1> a, b;
      ToVectors(MakeInputs(k), a, b);
      bench::Begin(kEkfMacFloat);
      ja::core::spike::StepStructuredMac(c, d, a, b, st);
      bench::End();
    }
    PrintValue("mac_float_theta", st.x(2));
  }
  {
    const Config<Q> c = MakeConfig<Q>();
    const Derived<Q> d = ja::core::spike::Derive(c);
    State<Q> st = MakeState<Q>();
    g_lcg = 777u;
    Hash h;
    ja::core::SaturationCount() = 0;
    for (int k = 0; k < kSteps; ++k) {
      Eigen::Matrix<Q, 4, 1> a, b;
      ToVectors(MakeInputs(k), a, b);
      bench::Begin(kEkfMacFixed);
      ja::core::spike::StepStructuredMac(c, d, a, b, st);
      bench::End();
      for (int i = 0; i < 3; ++i) h.Add(st.x(i).raw());
    }
    PrintCheck("ekf_mac_fixed_states", h.h);
    PrintCheck("ekf_mac_fixed_saturations", ja::core::SaturationCount());
    PrintValue("mac_fixed_theta", st.x(2).ToFloat());
  }
}

}  // namespace

int main() {
  const char* names[] = {"empty",           "float_mul",        "float_add",
                         "float_div",       "float_sin",        "float_atan2",
                         "float_sqrt",      "int32_mul",        "int64_mul",
                         "naive_q16_mul",   "fixed_mul",        "fixed_add",
                         "fixed_div",       "fixed_sin",        "fixed_cos",
                         "fixed_atan2",     "float_mat3_mul",   "fixed_mat3_mul",
                         "ekf_dense_float", "ekf_struct_float", "ekf_struct_fixed",
                         "ekf_mac_float",   "ekf_mac_fixed",    "fixed_mac4",
                         "float_dot4",      "fixed_dot4"};
  for (uint8_t i = 0; i < sizeof(names) / sizeof(names[0]); ++i) bench::Name(i + 1, names[i]);
  MeasurePrimitives();
  CheckFixedPrimitives();
  MeasureEkf();
  bench::Finish();
}
