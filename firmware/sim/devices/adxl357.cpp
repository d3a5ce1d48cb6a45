#include "sim/devices/adxl357.hpp"

#include <string.h>

#include <cmath>

namespace ja {
namespace sim {

namespace {
constexpr int32_t kMax20 = (1 << 19) - 1;
constexpr int32_t kMin20 = -(1 << 19);
constexpr double kPi = 3.14159265358979323846;
// HPF_CORNER codes 1..6: the -3 dB corner as a fraction of the ODR (code 0 off, 7 reserved).
constexpr double kHpfCornerPerOdr[8] = {0,         24.7e-4,   6.2084e-4, 1.5545e-4,
                                        0.3862e-4, 0.0954e-4, 0.0238e-4, 0};
// Conversions replayed one by one when time jumps (filter and FIFO); older ones are skipped.
constexpr uint64_t kMaxReplay = 4096;

int32_t Clamp20(int64_t v) {
  return static_cast<int32_t>(v > kMax20 ? kMax20 : v < kMin20 ? kMin20 : v);
}
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
  regs_[kRegActCount] = 0x01;
  counts_[0] = counts_[1] = counts_[2] = 0;
  data_ready_ = unread_ = false;
  clock_.Stop();
  ClearFifo();
}

void Adxl357::ClearFifo() {
  fifo_head_ = fifo_count_ = 0;
  fifo_axis_ = 0;
  fifo_byte_ = 0;
  fifo_overrun_ = false;
  activity_ = false;
  act_run_ = 0;
  for (int k = 0; k < 3; ++k) hpf_x_[k] = hpf_y_[k] = 0.0;
}

double Adxl357::lsb_per_g() const {
  const uint8_t code = regs_[kRegRange] & 3u;
  return 51200.0 / static_cast<double>(1u << (code ? code - 1u : 0u));
}

double Adxl357::hpf_corner_hz() const {
  uint8_t code = regs_[kRegFilter] & 0x0Fu;
  if (code > 10) code = 10;
  return kHpfCornerPerOdr[(regs_[kRegFilter] >> 4) & 7u] * 4000.0 / static_cast<double>(1u << code);
}

void Adxl357::Reclock() {
  if (regs_[kRegPowerCtl] & kPowerStandby) {
    clock_.Stop();
    ClearFifo();  // standby resets the digital functions, FIFO pointers included
    return;
  }
  uint8_t code = regs_[kRegFilter] & 0x0Fu;
  if (code > 10) code = 10;                      // 11..15 are reserved
  const uint64_t period_ns = 250000ull << code;  // 1 / (4000 Hz / 2^code)
  if (!clock_.running() || clock_.nominal_period_ns() != period_ns) {
    clock_.Start(now_ns(), period_ns);
  }
}

void Adxl357::set_oscillator(const Oscillator& o) {
  clock_.set_oscillator(o);
  clock_.Restart(now_ns());
}

void Adxl357::Update() {
  if (conversions_stopped()) return;
  uint64_t t_ns = 0;
  const uint64_t n = clock_.Advance(now_ns(), &t_ns);
  if (!n) return;
  CountConversions(n, &unread_);
  // Every conversion goes through the filter and into the FIFO, oldest first.
  const uint64_t replay = n < kMaxReplay ? n : kMaxReplay;
  for (uint64_t i = replay; i-- > 0;) {
    Convert(t_ns - i * clock_.period_ns());
    PushFifo();
    DetectActivity();
  }
  data_ready_ = true;
}

void Adxl357::Convert(uint64_t t_ns) {
  if (fault(FaultKind::kFrozen)) return;
  MotionSample m{{0, 0, 0}, {0, 0, 0}, false};
  if (motion_) motion_->Sample(t_ns, &m);
  const double lsb = kStandardGravity / lsb_per_g();
  const uint8_t mask = static_cast<uint8_t>(fault_param(FaultKind::kSaturate) & 7u);
  const double corner_hz = hpf_corner_hz();
  // First-order high-pass: y[n] = a (y[n-1] + x[n] - x[n-1]), a = exp(-2 pi fc / ODR). The
  // corner is a fixed fraction of the ODR: the nominal one (an off oscillator moves both).
  const double a =
      corner_hz > 0 ? std::exp(-2.0 * kPi * corner_hz * 1e-9 * clock_.nominal_period_ns()) : 0.0;
  for (int k = 0; k < 3; ++k) {
    double v = m.accel_mps2[k];
    if (corner_hz > 0) {
      const double y = a * (hpf_y_[k] + v - hpf_x_[k]);
      hpf_x_[k] = v;
      hpf_y_[k] = y;
      v = y;
    } else {
      hpf_x_[k] = v;  // switching the filter on later starts from the current input
      hpf_y_[k] = 0.0;
    }
    int32_t c = ToCounts(v, lsb, kMin20, kMax20);
    // OFFSET_x: two's complement, significance of XDATA[19:4], added after all other processing.
    const int16_t ofs =
        static_cast<int16_t>(regs_[kRegOffsetXH + 2 * k] << 8 | regs_[kRegOffsetXH + 2 * k + 1]);
    if (ofs) c = Clamp20(static_cast<int64_t>(c) + 16 * static_cast<int64_t>(ofs));
    if (fault(FaultKind::kSaturate) && (mask == 0 || (mask >> k) & 1u)) c = Rail(v, kMin20, kMax20);
    counts_[k] = c;
  }
}

void Adxl357::PushFifo() {
  for (int k = 0; k < 3; ++k) {
    if (fifo_count_ == kFifoEntries) {  // full: the oldest entry is lost
      fifo_overrun_ = true;
      fifo_head_ = (fifo_head_ + 1) % kFifoEntries;
      fifo_axis_ = static_cast<uint8_t>((fifo_axis_ + 1) % 3);
      --fifo_count_;
    }
    fifo_[(fifo_head_ + fifo_count_) % kFifoEntries] = counts_[k];
    ++fifo_count_;
  }
}

uint8_t Adxl357::FifoByte() {
  if (fifo_byte_ == 0) {
    uint32_t u = 0;
    uint8_t flags = kFifoEmpty;
    if (fifo_count_ > 0) {
      u = static_cast<uint32_t>(fifo_[fifo_head_]) & 0xFFFFFu;
      flags = fifo_axis_ == 0 ? kFifoMarkerX : 0;
      fifo_head_ = (fifo_head_ + 1) % kFifoEntries;
      --fifo_count_;
      fifo_axis_ = static_cast<uint8_t>((fifo_axis_ + 1) % 3);
    }
    fifo_word_[0] = static_cast<uint8_t>(u >> 12);
    fifo_word_[1] = static_cast<uint8_t>(u >> 4);
    fifo_word_[2] = static_cast<uint8_t>(((u & 0xFu) << 4) | flags);
  }
  const uint8_t b = fifo_word_[fifo_byte_];
  fifo_byte_ = static_cast<uint8_t>((fifo_byte_ + 1) % 3);
  return b;
}

// Activity: an ACT_EN axis whose |XDATA[18:3]| exceeds ACT_THRESH (unsigned, same significance)
// for ACT_COUNT conversions in a row.
void Adxl357::DetectActivity() {
  const uint8_t axes = regs_[kRegActEn] & 7u;
  if (!axes) {
    act_run_ = 0;
    return;
  }
  const int32_t thresh = (regs_[kRegActThreshH] << 8) | regs_[kRegActThreshH + 1];
  bool above = false;
  for (int k = 0; k < 3; ++k) {
    const int32_t mag = (counts_[k] < 0 ? -counts_[k] : counts_[k]) >> 3;
    if ((axes >> k) & 1u && mag > thresh) above = true;
  }
  act_run_ = above ? act_run_ + 1 : 0;
  const uint32_t need = regs_[kRegActCount] ? regs_[kRegActCount] : 1;
  if (act_run_ >= need) activity_ = true;
}

bool Adxl357::HoldsPointer(uint8_t reg) const { return reg == kRegFifoData && !burst_moved(); }

uint8_t Adxl357::ReadRegister(uint8_t reg) {
  if (reg <= kRegPartId) {
    if (!fault(FaultKind::kWrongId)) return regs_[reg];
    const uint32_t p = fault_param(FaultKind::kWrongId);
    return static_cast<uint8_t>(p ? p : static_cast<uint8_t>(~regs_[reg]));
  }
  if (reg == kRegStatus) {
    const int watermark = regs_[kRegFifoSamples] & 0x7F;
    const uint8_t s = static_cast<uint8_t>(
        (data_ready_ ? kStatusDataReady : 0) | (fifo_count_ >= watermark ? kStatusFifoFull : 0) |
        (fifo_overrun_ ? kStatusFifoOverrun : 0) | (activity_ ? kStatusActivity : 0));
    fifo_overrun_ = activity_ = false;
    return s;
  }
  if (reg == kRegFifoEntries) return static_cast<uint8_t>(fifo_count_);
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
  if (reg == kRegFifoData) return burst_moved() ? 0 : FifoByte();
  if (reg == kRegReset) return 0;
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
  // The high-pass corner may change while measuring; ODR and range may not.
  const uint8_t significant = reg == kRegFilter ? 0x0Fu : 0xFFu;
  if (measuring && (reg == kRegFilter || reg == kRegRange) &&
      ((regs_[reg] ^ value) & significant)) {
    ++counters_.config_violations;
  }
  regs_[reg] = value;
  if (reg == kRegFilter || reg == kRegPowerCtl) Reclock();
  return true;
}

}  // namespace sim
}  // namespace ja
