#include "sim/devices/adxl345.hpp"

#include <string.h>

#include <cmath>

namespace ja {
namespace sim {

namespace {
// Conversions replayed one by one when time jumps (FIFO and detection); older ones are skipped.
constexpr uint64_t kMaxReplay = 4096;
constexpr double kThreshGPerLsb = 0.0625;            // THRESH_TAP/ACT/INACT/FF
constexpr uint64_t kDurNsPerLsb = 625000;            // DUR
constexpr uint64_t kLatentNsPerLsb = 1250000;        // LATENT, WINDOW
constexpr uint64_t kTimeFfNsPerLsb = 5000000;        // TIME_FF
constexpr uint64_t kTimeInactNsPerLsb = 1000000000;  // TIME_INACT
}  // namespace

Adxl345::Adxl345(uint8_t addr7, const MotionSource* motion)
    : RegisterDevice(addr7), motion_(motion) {
  PowerOnReset();
}

void Adxl345::PowerOnReset() {
  memset(regs_, 0, sizeof regs_);
  regs_[kRegDevId] = kDevId;
  regs_[kRegBwRate] = kBwRateReset;
  for (int k = 0; k < 3; ++k) counts_[k] = sample_[k] = 0;
  data_ready_ = overrun_ = unread_ = false;
  clock_.Stop();
  ClearFifo();
  events_ = 0;
  tap_ = Tap::kIdle;
  tap_above_ = inact_timing_ = ff_timing_ = false;
  act_ref_set_ = inact_ref_set_ = link_seek_activity_ = false;
}

void Adxl345::ClearFifo() {
  fifo_head_ = fifo_count_ = 0;
  fifo_full_event_ = triggered_ = popped_ = false;
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
  if (!clock_.running() || clock_.nominal_period_ns() != period_ns) {
    clock_.Start(now_ns(), period_ns);
  }
}

void Adxl345::set_oscillator(const Oscillator& o) {
  clock_.set_oscillator(o);
  clock_.Restart(now_ns());
}

void Adxl345::Update() {
  if (conversions_stopped()) return;
  uint64_t t_ns = 0;
  const uint64_t n = clock_.Advance(now_ns(), &t_ns);
  if (!n) return;
  if (unread_ || n > 1) overrun_ = true;
  CountConversions(n, &unread_);
  const uint64_t replay = n < kMaxReplay ? n : kMaxReplay;
  for (uint64_t i = replay; i-- > 0;) {
    const uint64_t t = t_ns - i * clock_.period_ns();
    Convert(t);
    Detect(t);
    Store();
  }
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
    sample_[k] = c;
  }
}

// The newest conversion into the data registers (bypass) or the FIFO, then the trigger event.
void Adxl345::Store() {
  const uint8_t mode = regs_[kRegFifoCtl] & 0xC0u;
  if (mode == kFifoBypass) {
    for (int k = 0; k < 3; ++k) counts_[k] = sample_[k];
    return;
  }
  const bool stop_when_full = mode == kFifoFifo || (mode == kFifoTrigger && triggered_);
  bool keep = true;
  if (fifo_count_ == kFifoLevels) {
    fifo_full_event_ = true;
    if (stop_when_full) {
      keep = false;  // FIFO: collecting stops when full
    } else {
      fifo_head_ = (fifo_head_ + 1) % kFifoLevels;  // stream: the oldest is lost
      --fifo_count_;
    }
  }
  if (keep) {
    int32_t* slot = fifo_[(fifo_head_ + fifo_count_) % kFifoLevels];
    for (int k = 0; k < 3; ++k) slot[k] = sample_[k];
    if (++fifo_count_ == kFifoLevels) fifo_full_event_ = true;
  }
  if (mode == kFifoTrigger && !triggered_ && Pin((regs_[kRegFifoCtl] & kFifoTrigBit) != 0)) {
    triggered_ = true;  // keep the newest `samples` entries, then collect as in FIFO mode
    const int keep_n = regs_[kRegFifoCtl] & 0x1F;
    while (fifo_count_ > keep_n) {
      fifo_head_ = (fifo_head_ + 1) % kFifoLevels;
      --fifo_count_;
    }
    fifo_full_event_ = fifo_count_ == kFifoLevels;
  }
  if (fifo_count_ > 0) {
    for (int k = 0; k < 3; ++k) counts_[k] = fifo_[fifo_head_][k];
  }
}

void Adxl345::OnStop() {
  // The end of a read of the data registers pops the FIFO: the next entry moves into them.
  if (popped_ && fifo_mode() && fifo_count_ > 0) {
    fifo_head_ = (fifo_head_ + 1) % kFifoLevels;
    --fifo_count_;
    fifo_full_event_ = false;
    if (fifo_count_ > 0) {
      for (int k = 0; k < 3; ++k) counts_[k] = fifo_[fifo_head_][k];
    }
  }
  popped_ = false;
}

// Activity, inactivity, free fall and taps on one conversion (datasheet "Interrupts").
void Adxl345::Detect(uint64_t t_ns) {
  const uint8_t en = regs_[kRegIntEnable];
  if (!(en & (kIntSingleTap | kIntDoubleTap | kIntActivity | kIntInactivity | kIntFreeFall))) {
    return;
  }
  double g[3];
  const double g_per_count = lsb_mps2() / kStandardGravity;
  for (int k = 0; k < 3; ++k) g[k] = sample_[k] * g_per_count;
  const uint8_t ctl = regs_[kRegActInactCtl];
  const bool link = regs_[kRegPowerCtl] & kPowerLink;

  // Activity: any participating axis above THRESH_ACT (ac: relative to the value when the
  // detection started).
  const double thr_act = regs_[kRegThreshAct] * kThreshGPerLsb;
  if ((en & kIntActivity) && (ctl & 0x70u) && (!link || link_seek_activity_)) {
    const bool ac = ctl & 0x80u;
    if (ac && !act_ref_set_) {
      for (int k = 0; k < 3; ++k) act_ref_g_[k] = g[k];
      act_ref_set_ = true;
    }
    uint8_t axes = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = ac ? g[k] - act_ref_g_[k] : g[k];
      if ((ctl & (0x40u >> k)) && std::fabs(d) > thr_act)
        axes = static_cast<uint8_t>(axes | (0x40u >> k));
    }
    if (axes) {
      events_ |= kIntActivity;
      regs_[kRegActTapStatus] = static_cast<uint8_t>((regs_[kRegActTapStatus] & ~0x70u) | axes);
      if (link) {
        link_seek_activity_ = false;
        inact_timing_ = inact_ref_set_ = false;
      }
    }
  } else {
    act_ref_set_ = false;
  }

  // Inactivity: every participating axis below THRESH_INACT for TIME_INACT seconds (ac: relative
  // to a reference taken again whenever the threshold is exceeded).
  const double thr_inact = regs_[kRegThreshInact] * kThreshGPerLsb;
  if ((en & kIntInactivity) && (ctl & 0x07u) && (!link || !link_seek_activity_)) {
    const bool ac = ctl & 0x08u;
    if (ac && !inact_ref_set_) {
      for (int k = 0; k < 3; ++k) inact_ref_g_[k] = g[k];
      inact_ref_set_ = true;
    }
    bool still = true;
    for (int k = 0; k < 3; ++k) {
      const double d = ac ? g[k] - inact_ref_g_[k] : g[k];
      if ((ctl & (0x04u >> k)) && std::fabs(d) >= thr_inact) still = false;
    }
    if (!still) {
      inact_timing_ = false;
      if (ac) {
        for (int k = 0; k < 3; ++k) inact_ref_g_[k] = g[k];
      }
    } else {
      if (!inact_timing_) {
        inact_timing_ = true;
        inact_since_ns_ = t_ns;
      }
      if (t_ns - inact_since_ns_ >= regs_[kRegTimeInact] * kTimeInactNsPerLsb) {
        events_ |= kIntInactivity;
        if (link) {
          link_seek_activity_ = true;
          act_ref_set_ = false;
        }
      }
    }
  } else {
    inact_timing_ = inact_ref_set_ = false;
  }

  // Free fall: every axis below THRESH_FF for TIME_FF.
  const double thr_ff = regs_[kRegThreshFf] * kThreshGPerLsb;
  if ((en & kIntFreeFall) && thr_ff > 0) {
    const bool falling =
        std::fabs(g[0]) < thr_ff && std::fabs(g[1]) < thr_ff && std::fabs(g[2]) < thr_ff;
    if (!falling) {
      ff_timing_ = false;
    } else {
      if (!ff_timing_) {
        ff_timing_ = true;
        ff_since_ns_ = t_ns;
      }
      if (t_ns - ff_since_ns_ >= regs_[kRegTimeFf] * kTimeFfNsPerLsb) events_ |= kIntFreeFall;
    }
  } else {
    ff_timing_ = false;
  }

  DetectTap(t_ns, g);
}

// Single and double taps (datasheet Figures 28 and 29): above THRESH_TAP for at most DUR; a second
// such event starting after LATENT and within WINDOW of the first's end is a double tap; with
// the suppress bit, acceleration above the threshold before the window invalidates it.
void Adxl345::DetectTap(uint64_t t_ns, const double g[3]) {
  const uint8_t en = regs_[kRegIntEnable];
  const uint8_t axes = regs_[kRegTapAxes] & 0x07u;
  const bool suppress = regs_[kRegTapAxes] & 0x08u;
  const double thr = regs_[kRegThreshTap] * kThreshGPerLsb;
  const uint64_t dur_ns = regs_[kRegDur] * kDurNsPerLsb;
  const uint64_t latent_ns = regs_[kRegLatent] * kLatentNsPerLsb;
  const uint64_t window_ns = regs_[kRegWindow] * kLatentNsPerLsb;
  if (!(en & (kIntSingleTap | kIntDoubleTap)) || thr <= 0 || dur_ns == 0 || axes == 0) {
    tap_ = Tap::kIdle;
    tap_above_ = false;
    return;
  }
  uint8_t which = 0;
  for (int k = 0; k < 3; ++k) {
    if ((axes & (0x04u >> k)) && std::fabs(g[k]) > thr)
      which = static_cast<uint8_t>(which | (0x04u >> k));
  }
  const bool above = which != 0;
  const bool rising = above && !tap_above_;
  tap_above_ = above;
  const bool double_on = (en & kIntDoubleTap) && latent_ns > 0 && window_ns > 0;

  if (tap_ == Tap::kLatency && t_ns - tap_end_ns_ >= latent_ns) tap_ = Tap::kWindow;
  if (tap_ == Tap::kWindow && t_ns - tap_end_ns_ > latent_ns + window_ns) tap_ = Tap::kIdle;

  if (tap_ == Tap::kIdle) {
    if (rising) {
      tap_ = Tap::kFirst;
      tap_start_ns_ = t_ns;
      regs_[kRegActTapStatus] = static_cast<uint8_t>((regs_[kRegActTapStatus] & ~0x07u) | which);
    }
  } else if (tap_ == Tap::kFirst || tap_ == Tap::kSecond) {
    if (above) {
      if (t_ns - tap_start_ns_ > dur_ns) tap_ = Tap::kWaitBelow;  // too long for a tap
    } else if (tap_ == Tap::kSecond) {
      events_ |= kIntDoubleTap;
      tap_ = Tap::kIdle;
    } else {
      if (en & kIntSingleTap) events_ |= kIntSingleTap;
      tap_end_ns_ = t_ns;
      tap_ = double_on ? Tap::kLatency : Tap::kIdle;
    }
  } else if (tap_ == Tap::kLatency) {
    if (above && suppress) tap_ = Tap::kWaitBelow;
  } else if (tap_ == Tap::kWindow) {
    if (rising) {
      tap_ = Tap::kSecond;
      tap_start_ns_ = t_ns;
    } else if (above && suppress) {
      tap_ = Tap::kWaitBelow;
    }
  } else if (!above) {  // kWaitBelow
    tap_ = Tap::kIdle;
  }
}

uint8_t Adxl345::IntSource() const {
  uint8_t s = events_;
  const int samples = regs_[kRegFifoCtl] & 0x1F;
  if (fifo_mode()) {
    if (fifo_count_ > 0) s |= kIntDataReady;
    if (fifo_count_ >= samples) s |= kIntWatermark;
    if (fifo_full_event_) s |= kIntOverrun;
  } else {
    if (data_ready_) s |= kIntDataReady;
    if (samples == 0) s |= kIntWatermark;  // bypass: 0 entries >= samples
    if (overrun_) s |= kIntOverrun;
  }
  return s;
}

bool Adxl345::Pin(bool int2) const {
  const uint8_t active = static_cast<uint8_t>(IntSource() & regs_[kRegIntEnable]);
  const uint8_t map = regs_[kRegIntMap];
  return (active & (int2 ? map : static_cast<uint8_t>(~map))) != 0;
}

bool Adxl345::int1() const { return Pin(false); }
bool Adxl345::int2() const { return Pin(true); }

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
    const uint8_t s = IntSource();
    events_ = 0;  // the function bits clear on this read; data-ready, watermark, overrun do not
    return s;
  }
  if (reg >= kRegDataX0 && reg < kRegDataX0 + 6) {
    const int i = reg - kRegDataX0;
    const uint16_t v = Encoded(i / 2);
    if (unread_) ++counters_.samples_read;
    data_ready_ = overrun_ = unread_ = false;
    popped_ = true;
    return static_cast<uint8_t>((i & 1) ? v >> 8 : v & 0xFFu);
  }
  if (reg == kRegFifoStatus) {
    return static_cast<uint8_t>((triggered_ ? kFifoStatusTrig : 0) | fifo_count_);
  }
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
  if (reg == kRegFifoCtl && (value & 0xC0u) == kFifoBypass) ClearFifo();  // resets trigger mode
  if (reg == kRegIntEnable || reg == kRegActInactCtl || reg == kRegPowerCtl) {
    act_ref_set_ = inact_ref_set_ = false;  // ac coupling: the references start again
  }
  return true;
}

}  // namespace sim
}  // namespace ja
