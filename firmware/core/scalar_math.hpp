// One spelling of the elementary functions for every core scalar, so a filter written once
// instantiates with float (libm) and with Fixed<F> (tables, fixed_trig.hpp).
#pragma once

#include <math.h>

#include "fixed_trig.hpp"

namespace ja {
namespace core {

inline float Sin(float angle_rad) { return sinf(angle_rad); }
inline float Cos(float angle_rad) { return cosf(angle_rad); }
inline float Atan2(float y, float x) { return atan2f(y, x); }
/// atan2 with the result type named (Fixed: computed straight into that format).
template <class R>
inline float Atan2To(float y, float x) {
  return atan2f(y, x);
}
inline void SinCos(float angle_rad, float& s, float& c) {
  s = sinf(angle_rad);
  c = cosf(angle_rad);
}

/// Float twin of Accumulator<Fixed<F>> (fixed_point.hpp): a plain running sum.
template <>
class Accumulator<float> {
 public:
  void Add(float a, float b) { sum_ += a * b; }
  void Subtract(float a, float b) { sum_ -= a * b; }
  void AddValue(float v) { sum_ += v; }
  float Result() const { return sum_; }

 private:
  float sum_ = 0.0f;
};

/// Scalar from a float constant (configuration time).
template <class S>
inline S FromFloat(float v) {
  return S(v);
}

}  // namespace core
}  // namespace ja
