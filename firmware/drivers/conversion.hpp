// Raw counts -> SI and -> fixed point: pure functions, the same on every platform.
#pragma once

#include <stdint.h>

#include "core/fixed_point.hpp"

namespace ja {
namespace drivers {

constexpr float kStandardGravity = 9.80665f;  // m/s^2 per g

/// counts * scale, in m/s^2 (float; host tools and tests).
inline float CountsToMps2(int32_t counts, float mps2_per_count) {
  return static_cast<float>(counts) * mps2_per_count;
}

/// counts * scale as Fixed<F> m/s^2, exact and saturating: the raw result is
/// round(counts * scale_raw), i.e. scale is given in Fixed<F> raw units per count.
template <int F>
inline core::Fixed<F> CountsToFixed(int32_t counts, core::Fixed<F> mps2_per_count) {
  const core::detail::Wide p = core::detail::MultiplyWide(counts, mps2_per_count.raw());
  return core::Fixed<F>::FromRaw(core::detail::SaturateWide(p.lo, p.hi));
}

/// Sign-extends the low `bits` bits of v (two's complement), without shifting negatives.
inline int32_t SignExtend(uint32_t v, uint8_t bits) {
  const uint32_t sign = static_cast<uint32_t>(1) << (bits - 1);
  const uint32_t masked = v & ((sign << 1) - 1u);
  return (masked & sign) ? -static_cast<int32_t>((sign << 1) - masked)
                         : static_cast<int32_t>(masked);
}

}  // namespace drivers
}  // namespace ja
