#include "sim/devices/adxl345.hpp"

#include <string.h>

namespace ja {
namespace sim {

Adxl345::Adxl345(uint8_t addr7, const MotionSource* motion)
    : RegisterDevice(addr7), motion_(motion) {
  PowerOnReset();
}

void Adxl345::PowerOnReset() {
  memset(regs_, 0, sizeof regs_);
  regs_[kRegDevId] = kDevId;
  regs_[kRegBwRate] = kBwRateReset;
  counts_[0] = counts_[1] = counts_[2] = 0;
  data_ready_ = overrun_ = unread_ = false;
  clock_.Stop();
}

double Adxl345::lsb_mps2() const {
  const uint8_t f = regs_[kRegDataFormat];
  const double g = (f & kFormatFullRes) ? kGPerLsb : kGPerLsb * static_cast<double>(1u << (f & 3u));
  return g * kStandardGravity;
}

uint8_t Adxl345::Bits() const {
  const uint8_t f = regs_[kRegDataFormat];
  return static_cast<uint8_t>((f & kFormatFullRes) ? 10u + (f & 3u) : 10u);
}

void Adxl345::Reclock() {
  const uint8_t power = regs_[kRegPowerCtl];
  if (!(power & kPowerMeasure)) {
    clock_.Stop();
    return;
  }
  uint64_t period_ns;
  if (power & kPowerSleep) {
    period_ns = 125000000ull << (power & 3u);  // WAKEUP 8, 4, 2, 1 Hz
  } else {
    // ODR = 3200 Hz / 2^(15 - code): period = 312.5 us * 2^(15 - code).
    period_ns = 312500ull << (15u - (regs_[kRegBwRate] & 0x0Fu));
  }
  if (!clock_.running() || clock_.period_ns() != period_ns) clock_.Start(now_ns(), period_ns);
}

void Adxl345::Update() {
  if (conversions_stopped()) return;
  uint64_t t_ns = 0;
  const uint64_t n = clock_.Advance(now_ns(), &t_ns);
  if (!n) return;
  if (unread_ || n > 1) overrun_ = true;
  CountConversions(n, &unread_);
  Convert(t_ns);
  data_ready_ = true;
}

void Adxl345::Convert(uint64_t t_ns) {
  if (fault(FaultKind::kFrozen)) return;  // data-ready keeps coming, values stay
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (motion_) motion_->Sample(t_ns, &m);
  const int32_t hi = (1 << (Bits() - 1)) - 1, lo = -(1 << (Bits() - 1));
  const double lsb = lsb_mps2();
  const uint8_t mask = static_cast<uint8_t>(fault_param(FaultKind::kSaturate) & 7u);
  const uint8_t format = regs_[kRegDataFormat];
  const bool lsb_3mg9 = (format & kFormatFullRes) || (format & 3u) == 0;
  const bool lsb_zero = (regs_[kRegBwRate] & 0x0Fu) >= 0x0E && lsb_3mg9;
  for (int k = 0; k < 3; ++k) {
    const double ofs = static_cast<int8_t>(regs_[kRegOfsX + k]) * kOffsetGPerLsb * kStandardGravity;
    const double a = m.accel_mps2[k] + ofs;
    int32_t c = ToCounts(a, lsb, lo, hi);
    if (fault(FaultKind::kSaturate) && (mask == 0 || (mask >> k) & 1u)) c = Rail(a, lo, hi);
    if (lsb_zero) c &= ~1;
    counts_[k] = c;
  }
}

uint16_t Adxl345::Encoded(int axis) const {
  const uint16_t v = static_cast<uint16_t>(counts_[axis]);  // two's complement, sign-extended
  if (regs_[kRegDataFormat] & kFormatJustify) return static_cast<uint16_t>(v << (16u - Bits()));
  return v;
}

uint8_t Adxl345::ReadRegister(uint8_t reg) {
  if (reg == kRegDevId) {
    if (!fault(FaultKind::kWrongId)) return kDevId;
    const uint32_t p = fault_param(FaultKind::kWrongId);
    return static_cast<uint8_t>(p ? p : static_cast<uint8_t>(~kDevId));
  }
  if (reg == kRegIntSource) {
    const bool watermark = (regs_[kRegFifoCtl] & 0x1Fu) == 0;  // bypass: 0 entries >= samples
    return static_cast<uint8_t>((data_ready_ ? kIntDataReady : 0) |
                                (watermark ? kIntWatermark : 0) | (overrun_ ? kIntOverrun : 0));
  }
  if (reg >= kRegDataX0 && reg < kRegDataX0 + 6) {
    const int i = reg - kRegDataX0;
    const uint16_t v = Encoded(i / 2);
    if (unread_) ++counters_.samples_read;
    data_ready_ = overrun_ = unread_ = false;
    return static_cast<uint8_t>((i & 1) ? v >> 8 : v & 0xFFu);
  }
  if (reg == kRegFifoStatus || reg == kRegActTapStatus) return 0;
  if (reg < sizeof regs_) return regs_[reg];
  return 0;
}

bool Adxl345::WriteRegister(uint8_t reg, uint8_t value) {
  const bool writable = (reg >= 0x1D && reg <= 0x2A) || (reg >= kRegBwRate && reg <= kRegIntMap) ||
                        reg == kRegDataFormat || reg == kRegFifoCtl;
  if (!writable) {
    ++counters_.writes_ignored;
    return true;  // the part ACKs and drops writes to read-only and reserved registers
  }
  regs_[reg] = value;
  if (reg == kRegBwRate || reg == kRegPowerCtl) Reclock();
  return true;
}

}  // namespace sim
}  // namespace ja
