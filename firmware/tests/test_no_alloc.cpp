// No dynamic allocation in the core: this binary replaces the global allocation functions with
// ones that abort, then runs the EKF spike (float and fixed) through Eigen. Built without
// sanitizers (they supply their own operator new).
#include <cstdio>
#include <cstdlib>
#include <new>

#include "core/fixed_eigen.hpp"
#include "core/joint_filter.hpp"
#include "platform/avr/bench/ekf_spike.hpp"

void* operator new(std::size_t) {
  std::fputs("test_no_alloc: operator new called\n", stderr);
  std::abort();
}
void* operator new[](std::size_t) {
  std::fputs("test_no_alloc: operator new[] called\n", stderr);
  std::abort();
}
void operator delete(void*) noexcept { std::abort(); }
void operator delete[](void*) noexcept { std::abort(); }
void operator delete(void*, std::size_t) noexcept { std::abort(); }
void operator delete[](void*, std::size_t) noexcept { std::abort(); }

namespace {
template <class S>
int RunSpike() {
  using namespace ja::core::spike;
  Config<S> c;
  for (LinkArray<S>* l : {&c.a, &c.b}) {
    l->g_omega2 << S(-5.0f), S(0.25f), S(5.0f), S(-0.25f);
    l->g_alpha << S(0.25f), S(5.0f), S(-0.25f), S(-5.0f);
    l->f << S(1.25f), S(0.0f), S(-0.25f), S(0.0f), S(0.0f), S(1.25f), S(0.0f), S(-0.25f);
  }
  c.dt = S(0.002f);
  c.sigma2 = S(0.0038f);
  const Derived<S> d = Derive(c);
  State<S> st;
  st.x.setConstant(S(0));
  st.p.setIdentity();
  Eigen::Matrix<S, 4, 1> a, b;
  a << S(0.1f), S(-0.2f), S(0.3f), S(0.05f);
  b << S(-0.1f), S(0.2f), S(0.1f), S(0.4f);
  for (int k = 0; k < 10; ++k) {
    StepStructured(c, d, a, b, st);
    StepDense(c, a, b, st);
  }
  return static_cast<int>(static_cast<float>(st.x(2)) * 1000.0f);
}

// The shipped joint filter: configuration, reset and steps.
template <class P>
int RunJointFilter() {
  using ja::core::ArrayGeometry;
  const ArrayGeometry<2> ga{
      {{0.25f, 0.0f}, {0.025f, 0.0f}}, {0.3f, 0.0f}, {4e-4f, 4e-4f, 4e-4f, 4e-4f}};
  const ArrayGeometry<2> gb{
      {{0.05f, 0.0f}, {0.275f, 0.0f}}, {0.0f, 0.0f}, {4e-4f, 4e-4f, 4e-4f, 4e-4f}};
  ja::core::Settings<P, 2> s;
  if (!ja::core::Configure<P, 2>(ga, gb, 0.002f, s)) return -1;
  ja::core::FilterState<P> st;
  ja::core::Reset(st);
  Eigen::Matrix<typename P::Accel, 4, 1> a, b;
  for (int j = 0; j < 4; ++j) {
    a(j) = typename P::Accel(0.5f * static_cast<float>(j) - 0.3f);
    b(j) = typename P::Accel(0.2f - 0.4f * static_cast<float>(j));
  }
  for (int k = 0; k < 200; ++k) ja::core::Step<P, 2>(s, a, b, st);
  return static_cast<int>(ja::core::ToFloat(st.theta) * 1000.0f);
}
}  // namespace

int main() {
  const int fa = RunJointFilter<ja::core::FloatPolicy>();
  const int fb = RunJointFilter<ja::core::FixedPolicy>();
  std::printf("test_no_alloc: joint filter without allocation (theta x1000: %d, %d)\n", fa, fb);
  const int a = RunSpike<float>();
  const int b = RunSpike<ja::core::Fixed<24>>();
  std::printf("test_no_alloc: no allocation (theta x1000: %d, %d)\n", a, b);
  return 0;
}
