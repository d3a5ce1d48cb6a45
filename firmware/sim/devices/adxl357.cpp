#include "sim/devices/adxl357.hpp"

#include <string.h>

namespace ja {
namespace sim {

namespace {
constexpr int32_t kMax20 = (1 << 19) - 1;
constexpr int32_t kMin20 = -(1 << 19);
}  // namespace

Adxl357::Adxl357(uint8_t addr7, const MotionSource* motion)
    : RegisterDevice(addr7), motion_(motion) {
  PowerOnReset();
}

void Adxl357::PowerOnReset() {
  memset(regs_, 0, sizeof regs_);
  regs_[kRegDevIdAd] = kDevIdAd;
  regs_[kRegDevIdMst] = kDevIdMst;
  regs_[kRegPartId] = kPartId;
  regs_[kRegRevId] = kRevId;
  regs_[kRegFifoSamples] = kFifoSamplesReset;
  regs_[kRegRange] = kRangeReset;
  regs_[kRegPowerCtl] = kPowerStandby;
  counts_[0] = counts_[1] = counts_[2] = 0;
  data_ready_ = unread_ = false;
  clock_.Stop();
}

double Adxl357::lsb_per_g() const {
  const uint8_t code = regs_[kRegRange] & 3u;
  return 51200.0 / static_cast<double>(1u << (code ? code - 1u : 0u));
}

void Adxl357::Reclock() {
  if (regs_[kRegPowerCtl] & kPowerStandby) {
    clock_.Stop();
    return;
  }
  uint8_t code = regs_[kRegFilter] & 0x0Fu;
  if (code > 10) code = 10;                      // 11..15 are reserved
  const uint64_t period_ns = 250000ull << code;  // 1 / (4000 Hz / 2^code)
  if (!clock_.running() || clock_.period_ns() != period_ns) clock_.Start(now_ns(), period_ns);
}

void Adxl357::Update() {
  if (conversions_stopped()) return;
  uint64_t t_ns = 0;
  const uint64_t n = clock_.Advance(now_ns(), &t_ns);
  if (!n) return;
  CountConversions(n, &unread_);
  Convert(t_ns);
  data_ready_ = true;
}

void Adxl357::Convert(uint64_t t_ns) {
  if (fault(FaultKind::kFrozen)) return;
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (motion_) motion_->Sample(t_ns, &m);
  const double lsb = kStandardGravity / lsb_per_g();
  const uint8_t mask = static_cast<uint8_t>(fault_param(FaultKind::kSaturate) & 7u);
  for (int k = 0; k < 3; ++k) {
    const double a = m.accel_mps2[k];
    int32_t c = ToCounts(a, lsb, kMin20, kMax20);
    if (fault(FaultKind::kSaturate) && (mask == 0 || (mask >> k) & 1u)) c = Rail(a, kMin20, kMax20);
    counts_[k] = c;
  }
}

uint8_t Adxl357::ReadRegister(uint8_t reg) {
  if (reg <= kRegPartId) {
    if (!fault(FaultKind::kWrongId)) return regs_[reg];
    const uint32_t p = fault_param(FaultKind::kWrongId);
    return static_cast<uint8_t>(p ? p : static_cast<uint8_t>(~regs_[reg]));
  }
  if (reg == kRegStatus) return data_ready_ ? kStatusDataReady : 0;
  if (reg == kRegTemp2) return static_cast<uint8_t>(kTemp25C >> 8);
  if (reg == kRegTemp1) return static_cast<uint8_t>(kTemp25C & 0xFFu);
  if (reg >= kRegXData3 && reg < kRegXData3 + 9) {
    const int i = reg - kRegXData3;
    const uint32_t u = static_cast<uint32_t>(counts_[i / 3]) & 0xFFFFFu;
    if (unread_) ++counters_.samples_read;
    data_ready_ = unread_ = false;
    switch (i % 3) {
      case 0:
        return static_cast<uint8_t>(u >> 12);
      case 1:
        return static_cast<uint8_t>(u >> 4);
      default:
        return static_cast<uint8_t>((u & 0xFu) << 4);
    }
  }
  if (reg == kRegFifoEntries || reg == kRegFifoData || reg == kRegReset) return 0;
  if (reg < sizeof regs_) return regs_[reg];
  return 0;
}

bool Adxl357::WriteRegister(uint8_t reg, uint8_t value) {
  if (reg == kRegReset) {
    if (value == kResetCode) PowerOnReset();
    return true;
  }
  if (reg < kRegOffsetXH || reg > kRegSelfTest) {
    ++counters_.writes_ignored;
    return true;
  }
  const bool measuring = !(regs_[kRegPowerCtl] & kPowerStandby);
  if (measuring && (reg == kRegFilter || reg == kRegRange) && regs_[reg] != value) {
    ++counters_.config_violations;
  }
  regs_[reg] = value;
  if (reg == kRegFilter || reg == kRegPowerCtl) Reclock();
  return true;
}

}  // namespace sim
}  // namespace ja
