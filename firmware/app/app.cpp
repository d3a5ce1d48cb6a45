#include "app/app.hpp"

#include <string.h>

#include "protocol/messages.hpp"

namespace ja {
namespace app {

namespace {

using proto::ErrorCode;

constexpr uint8_t kKnownStreamBits = proto::stream_mode::kSamples | proto::stream_mode::kEstimate |
                                     proto::stream_mode::kSampleEstimate |
                                     proto::stream_mode::kStatus |
                                     proto::stream_mode::kLeanEstimate;
// Status bits that trigger a status frame when they change (stale toggles with the ODR).
constexpr uint8_t kFaultBits = proto::sensor_status::kNack | proto::sensor_status::kWrongId |
                               proto::sensor_status::kSaturated | proto::sensor_status::kFrozen |
                               proto::sensor_status::kNotConfigured |
                               proto::sensor_status::kBadCalibration;

/// Datasheet noise density on x and y, µg/sqrt(Hz) (docs/sensors.md §A; host sensors.py).
float DensityUg(uint8_t model) {
  switch (static_cast<proto::SensorModel>(model)) {
    case proto::SensorModel::kAdxl345:
      return 290.0f;
    case proto::SensorModel::kAdxl357:
      return 80.0f;
    case proto::SensorModel::kBno055:
      return 150.0f;
    default:
      return 0.0f;
  }
}

/// Bytes of a sensor's sample read (its driver's burst; App::ReadDelayUs).
uint8_t SampleReadBytes(uint8_t model) {
  switch (static_cast<proto::SensorModel>(model)) {
    case proto::SensorModel::kAdxl345:
      return drivers::adxl345::kDataBytes;
    case proto::SensorModel::kAdxl357:
      return drivers::adxl357::kDataBytes;
    case proto::SensorModel::kBno055:
      return drivers::bno055::kAccDataBytes;
    default:
      return 0;
  }
}

/// Whether any sensor of the rig is behind the multiplexer.
bool UsesMux(const Config& c) {
  for (uint8_t i = 0; i < c.sensor_count; ++i) {
    if (c.sensors[i].mux_channel < drivers::tca9548a::kChannels) return true;
  }
  return false;
}

/// The multiplexer write the sample batch puts in front of the read of a sensor on channel `ch`
/// (>= kChannels: on the bus itself), given the channel it selected last (`*channel`, updated;
/// kChannels: every channel off): a select when the channel changes, and every channel off in
/// front of a sensor on the bus itself while one may be on (as Tca9548aRoot does), so a part at
/// its address there stays out.
enum class MuxWrite : uint8_t { kNone, kAllOff, kSelect };
MuxWrite MuxWriteBefore(uint8_t ch, bool uses_mux, uint8_t* channel) {
  constexpr uint8_t kAllOff = drivers::tca9548a::kChannels;
  if (ch >= drivers::tca9548a::kChannels) {
    if (!uses_mux || *channel == kAllOff) return MuxWrite::kNone;
    *channel = kAllOff;
    return MuxWrite::kAllOff;
  }
  if (ch == *channel) return MuxWrite::kNone;
  *channel = ch;
  return MuxWrite::kSelect;
}

/// `rate` bounded by `cap` (0: no bound).
uint16_t BoundedBy(uint16_t rate, uint16_t cap) { return cap != 0 && cap < rate ? cap : rate; }

/// A held rate within the set_rate range.
uint16_t WithinRateRange(uint32_t held) {
  return static_cast<uint16_t>(held > kMaxRateHz   ? kMaxRateHz
                               : held < kMinRateHz ? kMinRateHz
                                                   : held);
}

uint16_t AddSaturating16(uint16_t a, uint32_t b) {
  const uint32_t s = a + b;
  return s > 0xFFFF ? static_cast<uint16_t>(0xFFFF) : static_cast<uint16_t>(s);
}

bool Due(uint32_t now, uint32_t since, uint32_t interval) { return now - since >= interval; }

/// Slot `slot`'s calibration as stored in EEPROM, read straight from the image (no copy of the
/// whole configuration: ReadStoredPayload checks the CRC over the bytes as they are read). False
/// when the image is missing, of another layout, or fails its CRC. Offsets follow
/// SerialiseConfig: rate (2), joints (16), count (1), sensors (kMaxSensors x 17), then 48 bytes
/// of calibration per slot.
bool ReadStoredCalibration(Eeprom& eeprom, uint8_t slot, Calibration* out) {
  const uint16_t first = static_cast<uint16_t>(2 + 16 + 1 + kMaxSensors * 17 + slot * 48);
  uint8_t cal[48];
  if (ReadStoredPayload(eeprom, first, sizeof cal, cal) !=
      static_cast<uint8_t>(proto::EepromState::kOk)) {
    return false;
  }
  for (int j = 0; j < 9; ++j) out->s_q24[j] = proto::get_i32(cal + 4 * j);
  for (int j = 0; j < 3; ++j) out->o_umps2[j] = proto::get_i32(cal + 36 + 4 * j);
  return true;
}

}  // namespace

App::App(const Hal& hal)
    : hal_(hal),
      mux_(hal.i2c, kMuxAddress),
      channels_{{mux_, 0}, {mux_, 1}, {mux_, 2}, {mux_, 3},
                {mux_, 4}, {mux_, 5}, {mux_, 6}, {mux_, 7}},
      root_(mux_) {
  SetDefaults(config_, FactoryRate());
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) chosen_[l][k] = -1;
  }
  memset(last_status_mask_, 0, sizeof last_status_mask_);
  core::Reset(filter_);
}

void App::Begin() {
  FinishBatch();  // a soft restart: let the bus settle, drop the reads
  seq_ = 0;
  rx_.reset();
  stream_mode_ = 0;
  status_interval_us_ = 0;
  restart_pending_ = false;
  factory_reset_pending_ = false;
  overruns_ = 0;
  uart_drops_ = 0;
  loops_ = 0;
  uptime_ms_ = 0;
  uptime_rem_us_ = 0;
  filter_resets_ = 0;
  eeprom_state_ = LoadConfig(hal_.eeprom, config_, FactoryRate());
  mux_.Invalidate();
  BindAllSensors();
  // A BNO055 does not answer during its power-up boot: keep re-probing the ones that NACK for
  // up to kBootWaitMs before the hello, so a cold start reports the real inventory.
  const auto booting = [this](uint8_t i) {
    return config_.sensors[i].model == static_cast<uint8_t>(proto::SensorModel::kBno055) &&
           (sensors_[i].status() & proto::sensor_status::kNack) != 0;
  };
  for (uint16_t waited = 0; waited < kBootWaitMs; waited += kBootRetryMs) {
    bool waiting = false;
    for (uint8_t i = 0; i < config_.sensor_count; ++i) waiting = waiting || booting(i);
    if (!waiting) break;
    hal_.delay.WaitMs(kBootRetryMs);
    mux_.Invalidate();
    for (uint8_t i = 0; i < config_.sensor_count; ++i) {
      if (booting(i)) sensors_[i].Probe();
    }
  }
  SelectFilterSensors(true);
  ResetTiming();
  SendHello();
  if (hal_.batch != nullptr) StartBatch();  // the first loop collects these reads
  if (eeprom_state_ == static_cast<uint8_t>(proto::EepromState::kBadChecksumDefaults)) {
    SendLog(static_cast<uint8_t>(proto::LogLevel::kWarning),
            "EEPROM configuration has a bad checksum: running on factory defaults");
  } else if (eeprom_state_ == static_cast<uint8_t>(proto::EepromState::kNewerLayoutDefaults)) {
    SendLog(static_cast<uint8_t>(proto::LogLevel::kWarning),
            "EEPROM configuration is from a newer firmware: running on factory defaults");
  }
}

void App::ResetTiming() {
  period_us_ = 1000000u / config_.rate_hz;
  const uint32_t now = hal_.clock.NowUs();
  // Pipelined, the first loop collects the batch started now (Begin, a command that rebound
  // the sensors): a period from now, when it has ended. (At once, it waited a whole batch and
  // overran: ~7 overruns after each set_rate at 1 kHz on the Pico, until the loops caught up.)
  next_due_us_ = hal_.batch != nullptr ? now + period_us_ : now;
  last_probe_us_ = now;
  last_id_check_us_ = now;
  last_now_us_ = now;
  last_status_us_ = now;
  window_start_us_ = next_due_us_;  // the statistics count loops from the first one
  window_busy_us_ = 0;
  window_loops_ = 0;
}

void App::BindSensor(uint8_t slot) {
  // The samples of a batch still in flight belong to the old binding: taken first, and the bus
  // is idle for the probe.
  CollectPendingBatch();
  batches_[0].layout_ok = batches_[1].layout_ok = false;
  Sensor& s = sensors_[slot];
  if (slot >= config_.sensor_count) {
    SensorConfig none = config_.sensors[slot];
    none.model = static_cast<uint8_t>(proto::SensorModel::kNone);
    s.Bind(hal_.i2c, hal_.delay, none, config_.calibration[slot], config_.rate_hz);
    return;
  }
  const SensorConfig& c = config_.sensors[slot];
  drivers::I2cBus& bus = c.mux_channel < drivers::tca9548a::kChannels
                             ? static_cast<drivers::I2cBus&>(channels_[c.mux_channel])
                             : static_cast<drivers::I2cBus&>(root_);
  s.Bind(bus, hal_.delay, c, config_.calibration[slot], config_.rate_hz);
  s.Probe();
}

void App::BindAllSensors() {
  for (uint8_t i = 0; i < kMaxSensors; ++i) BindSensor(i);
  UpdateBusRate();
}

App::BusWork App::LoopBusWork() const {
  // Per transfer a START, 9 SCL a byte written (its ACK included: the address, then the
  // register or the multiplexer's mask), for a read a repeated START and 9 a byte read (the
  // address, then the data), a STOP. The batch's layout (BuildBatch, MuxWriteBefore) with every
  // sensor read.
  constexpr uint16_t kWrite = 1 + 9 * 2 + 1;  // a select or all-off write: 20
  const bool uses_mux = UsesMux(config_);
  uint8_t channel = 0xFF;  // as BuildBatch starts: none known
  BusWork w{0, 0};
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    const SensorConfig& s = config_.sensors[i];
    const uint8_t bytes = SampleReadBytes(s.model);
    if (bytes == 0) continue;  // no part in the slot: nothing read
    const MuxWrite write = MuxWriteBefore(s.mux_channel, uses_mux, &channel);
    if (write != MuxWrite::kNone) w.scl = static_cast<uint16_t>(w.scl + kWrite);
    if (write == MuxWrite::kSelect) ++w.selects;
    w.scl = static_cast<uint16_t>(w.scl + kWrite + 1 + 9 * (1 + bytes));  // ADXL345: 84
  }
  return w;
}

uint16_t App::LoopSclPeriods() const {
  const BusWork w = LoopBusWork();
  return w.selects != 0 ? static_cast<uint16_t>(w.scl + kReadBackSclPeriods) : w.scl;
}

void App::UpdateBusRate() {
  // The highest rate (10 Hz steps, within the set_rate range) whose SCL periods take at most
  // kSustainableBusNs of a second: a loop's batch plus, on average, 1 / SelectReadBackEvery of a
  // read-back (which depends on the rate). Here, at configuration, not in the loop: up to
  // 100 candidates of four divisions each (< 20 ms on the Mega; its bound, 760 Hz, takes 25).
  bus_rate_hz_ = 0;
  if (hal_.scl_period_ns != 0) {
    const BusWork w = LoopBusWork();
    const uint32_t read_back = w.selects != 0 ? kReadBackSclPeriods : 0u;
    bus_rate_hz_ = kMinRateHz;
    for (uint16_t rate = kMaxRateHz; rate >= kMinRateHz; rate = static_cast<uint16_t>(rate - 10)) {
      const uint8_t every = SelectReadBackEvery(w.selects, 1000000u / rate);
      const uint32_t loop_ns =
          (static_cast<uint32_t>(w.scl) * every + read_back) * hal_.scl_period_ns / every;
      if (loop_ns <= kSustainableBusNs / rate) {
        bus_rate_hz_ = rate;
        break;
      }
    }
  }
  sustainable_rate_hz_ = cpu_rate_hz_ != 0 ? BoundedBy(cpu_rate_hz_, bus_rate_hz_) : 0;
}

void App::ProbeDue(uint32_t now_us) {
  if (Due(now_us, last_id_check_us_, kIdCheckIntervalUs) && config_.sensor_count > 0) {
    // One working sensor's ID per interval, round robin: a swapped or failing part is caught
    // within count x 100 ms at the cost of one 1-byte read.
    last_id_check_us_ = now_us;
    id_cursor_ = static_cast<uint8_t>((id_cursor_ + 1) % config_.sensor_count);
    sensors_[id_cursor_].CheckId();
  }
  if (!Due(now_us, last_probe_us_, kProbeIntervalUs)) return;
  last_probe_us_ = now_us;
  // One faulted sensor per interval (round robin): a probe costs several transactions, and a
  // BNO055's mode switches wait ~28 ms.
  for (uint8_t k = 0; k < kMaxSensors; ++k) {
    const uint8_t i = static_cast<uint8_t>((probe_cursor_ + k) % kMaxSensors);
    if (sensors_[i].bound() && sensors_[i].needs_probe()) {
      sensors_[i].Probe();
      probe_cursor_ = static_cast<uint8_t>((i + 1) % kMaxSensors);
      return;
    }
  }
}

void App::SelectFilterSensors(bool force) {
  // The choice depends only on which sensors are usable (and on the configuration, whose
  // commands force a new choice): nothing to do while that set stays the same.
  uint8_t usable = 0;
  const Sensor* s = sensors_;  // pointers, not sensors_[i]: a multiplication each on the AVR
  for (uint8_t bit = 1, i = 0; i < config_.sensor_count;
       ++i, ++s, bit = static_cast<uint8_t>(bit << 1)) {
    if (s->usable()) usable = static_cast<uint8_t>(usable | bit);
  }
  if (!force && usable == usable_mask_) return;
  usable_mask_ = usable;
  int8_t pick[2][kFilterSensorsPerLink];
  uint8_t found[2] = {0, 0};
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) pick[l][k] = -1;
  }
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    const uint8_t l = config_.sensors[i].link;
    if (l > 1 || !sensors_[i].usable() || found[l] >= kFilterSensorsPerLink) continue;
    pick[l][found[l]++] = static_cast<int8_t>(i);
  }
  bool same = !force;
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) same = same && pick[l][k] == chosen_[l][k];
  }
  if (same) return;
  memcpy(chosen_, pick, sizeof chosen_);
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) {
      chosen_sensor_[l][k] = pick[l][k] < 0 ? nullptr : &sensors_[pick[l][k]];
    }
  }
  const bool enough = found[0] >= kFilterMinSensorsPerLink && found[1] >= kFilterMinSensorsPerLink;
  geometry_ok_ = enough && ConfigureFilter();
  filter_valid_ = geometry_ok_;
  core::Reset(filter_);
  filter_resets_ = AddSaturating16(filter_resets_, 1);
  if (enough && !geometry_ok_) {
    SendLog(static_cast<uint8_t>(proto::LogLevel::kWarning),
            "filter: rig geometry rejected (sensors too close together or constants out of range)");
  }
}

uint16_t App::ReadDelayUs(uint8_t slot) const {
  if (hal_.bus_byte_ns == 0 || slot >= config_.sensor_count) return 0;
  // The batch's layout (BuildBatch) with every sensor read: each multiplexer write (address,
  // control byte; MuxWriteBefore) and each read (address, register, address, data bytes); the
  // sample is taken where its read starts. Unverified selects (the select-and-read-back of one
  // channel a loop adds 1 byte) and START/STOP conditions are left out: < 0.1 of a sensor's read.
  const bool uses_mux = UsesMux(config_);
  uint8_t channel = 0xFF;  // as BuildBatch starts: none known
  uint32_t bytes = 0, first = 0;
  for (uint8_t i = 0; i <= slot; ++i) {
    const SensorConfig& s = config_.sensors[i];
    if (MuxWriteBefore(s.mux_channel, uses_mux, &channel) != MuxWrite::kNone) bytes += 2;
    if (i == 0) first = bytes;
    if (i == slot) break;
    bytes += 3u + SampleReadBytes(s.model);
  }
  const uint32_t us = ((bytes - first) * hal_.bus_byte_ns + 500u) / 1000u;
  return us > 0xFFFF ? static_cast<uint16_t>(0xFFFF) : static_cast<uint16_t>(us);
}

bool App::ConfigureFilter() {
  core::ArrayGeometry<kFilterSensorsPerLink> geo[2];
  const float rate = static_cast<float>(config_.rate_hz);
  for (int l = 0; l < 2; ++l) {
    geo[l].joint_m[0] = static_cast<float>(config_.joint_um[l][0]) * 1e-6f;
    geo[l].joint_m[1] = static_cast<float>(config_.joint_um[l][1]) * 1e-6f;
    geo[l].count = 0;
    for (int k = 0; k < kFilterSensorsPerLink; ++k) {
      geo[l].sensor_m[k][0] = geo[l].sensor_m[k][1] = 0.0f;
      geo[l].noise_var[2 * k] = geo[l].noise_var[2 * k + 1] = 0.0f;
      geo[l].read_delay_s[k] = 0.0f;
      if (chosen_[l][k] < 0) continue;
      ++geo[l].count;
      const SensorConfig& s = config_.sensors[chosen_[l][k]];
      geo[l].sensor_m[k][0] = static_cast<float>(s.x_um) * 1e-6f;
      geo[l].sensor_m[k][1] = static_cast<float>(s.y_um) * 1e-6f;
      geo[l].read_delay_s[k] =
          static_cast<float>(ReadDelayUs(static_cast<uint8_t>(chosen_[l][k]))) * 1e-6f;
      float var;
      if (config_.filter.accel_sigma_u != 0) {
        const float sigma = static_cast<float>(config_.filter.accel_sigma_u) * 1e-6f;
        var = sigma * sigma;
      } else {
        // sigma = density g sqrt(fs / 2) (docs/design.md §3) plus quantisation LSB^2 / 12.
        const float sigma = DensityUg(s.model) * 1e-6f * drivers::kStandardGravity;
        const float lsb = Mps2PerCount(s.model, s.range_g);
        var = sigma * sigma * (rate * 0.5f) + lsb * lsb / 12.0f;
      }
      geo[l].noise_var[2 * k] = var;
      geo[l].noise_var[2 * k + 1] = var;
    }
  }
  return core::Configure<FilterPolicy, kFilterSensorsPerLink>(geo[0], geo[1], 1.0f / rate,
                                                              filter_settings_);
}

uint32_t App::Poll() {
  if (restart_pending_) {
    restart_pending_ = false;
    if (factory_reset_pending_) EraseConfig(hal_.eeprom);
    factory_reset_pending_ = false;
    hal_.system.Reboot();
    return 0;
  }
  // At most one command a call: a command can take milliseconds (set_rate probes every sensor),
  // so a host sending faster than they are handled must not keep the loop (and the board's
  // watchdog kick between calls) waiting; the bytes after it stay in the receive buffer.
  bool handled = false;
  // A command waits (in the decoder) until its replies fit: see ReplyRoom.
  // (At most kReplyWaitMaxUs: a board whose buffer never holds that much still answers.)
  if (command_waiting_ && (hal_.serial.TxFree() >= ReplyRoom(rx_.header().msg_id) ||
                           hal_.clock.NowUs() - command_waiting_since_us_ >= kReplyWaitMaxUs)) {
    command_waiting_ = false;
    HandleCommandFrame();
    handled = true;
  }
  while (!command_waiting_ && !handled) {
    const int16_t b = hal_.serial.RxRead();
    if (b < 0) break;
    const proto::DecodeEvent e = rx_.push(static_cast<uint8_t>(b));
    if (e == proto::DecodeEvent::kFrame) {
      if (hal_.serial.TxFree() < ReplyRoom(rx_.header().msg_id)) {
        command_waiting_ = true;
        command_waiting_since_us_ = hal_.clock.NowUs();
        break;
      }
      HandleCommandFrame();
      handled = true;
      break;
    }
    if (e == proto::DecodeEvent::kVersionMismatch) {
      // A host of another protocol version: answer with hello in ours, so that it can refuse
      // the board naming both versions (docs/design.md §6) instead of waiting for a reply.
      SendHello();
      handled = true;
      break;
    }
  }
  if (restart_pending_) return 0;
  // After a command the next loop still finds this period's reads waiting.
  if (hal_.batch != nullptr && !batch_pending_) StartBatch();
  const uint32_t now = hal_.clock.NowUs();
  const int32_t wait = static_cast<int32_t>(next_due_us_ - now);
  if (wait > 0) {
    if (handled) return 0;  // more may be waiting
    // A waiting command: look again once a reply's worth of bytes has gone out.
    if (command_waiting_ && static_cast<uint32_t>(wait) > kReplyWaitUs) return kReplyWaitUs;
    return static_cast<uint32_t>(wait);
  }
  // The loop's time is its grid slot (APP.md "Timing"), not `now`, which trails it by the wake-up
  // latency (interrupts in flight at the deadline, a command handled first): on the AVR that made
  // t_us step 4944..5006 us at 200 Hz instead of the period.
  RunLoop(next_due_us_);
  next_due_us_ += period_us_;
  const uint32_t end = hal_.clock.NowUs();
  window_busy_us_ += end - now;
  const int32_t left = static_cast<int32_t>(next_due_us_ - end);
  if (left > 0) return static_cast<uint32_t>(left);
  // Overran (APP.md "Timing"): the next loop starts at once, stamped with the last grid slot at
  // or before its start — so a board asked for more than its work allows loops as fast as the
  // work allows (waiting for the next free slot instead halved a rate of 1-2x its capacity),
  // frames keep t_us on the grid, and the filter's time (StepPeriods of the slots) trails the
  // clock by less than a period, never drifting. One overrun counted per late loop.
  overruns_ = AddSaturating16(overruns_, 1);
  const uint32_t late = end - next_due_us_;
  if (late >= period_us_) next_due_us_ += late / period_us_ * period_us_;  // (divides when late)
  return 0;
}

void App::RunLoop(uint32_t now_us) {
  // Uptime and the statistics window.
  const uint32_t dt = now_us - last_now_us_;
  last_now_us_ = now_us;
  const uint8_t periods = StepPeriods(now_us - last_slot_us_, period_us_);
  last_slot_us_ = now_us;
  loop_periods_ = periods;  // the sensors' frozen test counts time (CollectBatch)
  uptime_rem_us_ += dt;
  // = rem / 1000 and rem % 1000, without the 32-bit divisions (~600 cycles each on the AVR)
  // for the usual dt of one period (<= 16 ms at >= 62.5 Hz).
  if (uptime_rem_us_ >= 16000u) {
    uptime_ms_ += uptime_rem_us_ / 1000u;
    uptime_rem_us_ %= 1000u;
  }
  while (uptime_rem_us_ >= 1000u) {
    uptime_rem_us_ -= 1000u;
    ++uptime_ms_;
  }
  const uint32_t window = now_us - window_start_us_;
  if (window >= kStatsWindowUs) {
    loop_rate_hz_ = static_cast<uint16_t>(
        (static_cast<uint32_t>(window_loops_) * 1000000u + window / 2) / window);
    const uint32_t busy = window_busy_us_ > window ? window : window_busy_us_;
    idle_permille_ = static_cast<uint16_t>(1000u - (busy / (window / 1000u)));
    // A loop busy b us holds 0.8 / b at >= 20 % asleep (10 Hz steps, within the set_rate range).
    // (A window of fewer than 10 loops, e.g. the one spanning Begin's probes, says nothing.)
    // held = 0.8 s / (busy / loops x scale), in 10 Hz steps: one division (this loop already
    // does three; each is ~670 cycles on the AVR, and the window's loop must keep its deadline).
    if (window_loops_ >= 10) {
      const uint32_t tens = busy != 0 ? sustain_scaled_ * window_loops_ / (busy * 10u) : 100u;
      cpu_rate_hz_ = WithinRateRange(tens * 10u);
      // ... and at most what the bus holds (UpdateBusRate, at configuration).
      sustainable_rate_hz_ = BoundedBy(cpu_rate_hz_, bus_rate_hz_);
    }
    window_start_us_ = now_us;
    window_busy_us_ = 0;
    window_loops_ = 0;
  }
  ++window_loops_;
  ++loops_;

  if (hal_.batch != nullptr) {
    // Pipelined (APP.md, "Pipelined sampling"): the reads started one period ago have ended;
    // the bus is free for this period's probe or ID check, then this period's reads start at
    // once, into the other batch, and run in the background while the CPU processes the
    // previous ones and steps the filter on them: one period of latency, and the bus may work
    // through the whole period.
    const SampleBatch* done = FinishBatch();
    ProbeDue(now_us);
    StartBatch();
    if (done != nullptr) CollectBatch(*done);
  } else {
    ProbeDue(now_us);
    Mark(activity::kCalibration);
    bool nack = false;
    for (uint8_t i = 0; i < config_.sensor_count; ++i) {
      sensors_[i].Sample(periods);
      nack = nack || (sensors_[i].status() & proto::sensor_status::kNack) != 0;
    }
    // A NACK behind the multiplexer may mean it lost its selection (reset, glitch): forget the
    // cached channel so the next access selects (and verifies) it again.
    if (nack) mux_.Invalidate();
  }
  Mark(activity::kOther);
  SelectFilterSensors(false);
  StepFilter(periods);
  Mark(activity::kFraming);
  Stream(now_us);
  Mark(activity::kOther);
}

void App::StartBatch() {
  SampleBatch& b = batches_[batch_next_];
  // The list only changes when a sensor is (re)bound or becomes ready or unready (a probe, a
  // NACK): built again then, otherwise started as it is (the board resets each status).
  uint8_t ready = 0;
  const Sensor* s = sensors_;
  for (uint8_t bit = 1, i = 0; i < config_.sensor_count;
       ++i, ++s, bit = static_cast<uint8_t>(bit << 1)) {
    if (s->sample_ready()) ready = static_cast<uint8_t>(ready | bit);
  }
  if (!b.layout_ok || ready != b.ready || config_.sensor_count != b.sensors) {
    BuildBatch(b);
    b.ready = ready;
    b.sensors = config_.sensor_count;
    b.layout_ok = true;
    read_back_every_ = SelectReadBackEvery(b.selects, period_us_);
  }
  // One select every read_back_every_ loops is read back (in turn), the others are plain
  // writes: each channel's selection is verified within max(its selects, kSelectVerifyUs), at
  // 3 TWI interrupts and 19 SCL less per unverified select (APP.md, "Pipelined sampling").
  if (b.selects != 0) {
    bool read_back = false;
    if (read_back_wait_ == 0) {
      read_back_wait_ = read_back_every_;
      read_back = true;
      if (++read_back_turn_ >= b.selects) read_back_turn_ = 0;
    }
    --read_back_wait_;
    for (uint8_t j = 0; j < b.selects; ++j) {
      b.transfers[b.select[j]].n = read_back && j == read_back_turn_ ? 1 : 0;
    }
  }
  mux_.Invalidate();  // the batch moves the selection behind the driver's back
  batch_pending_ = true;
  batch_next_ ^= 1;
  if (b.count != 0) hal_.batch->Start(b.transfers, b.count);
}

void App::BuildBatch(SampleBatch& b) {
  uint8_t n = 0;
  uint8_t channel = 0xFF;  // the channel the batch selected last (kChannels: none)
  const bool uses_mux = UsesMux(config_);
  uint8_t select = I2cTransfer::kNoDependency;
  b.selects = 0;
  for (uint8_t i = 0; i < kMaxSensors; ++i) b.read[i] = nullptr;
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    SampleBus::Transfer t;
    if (!sensors_[i].PrepareSample(&t)) continue;
    const uint8_t ch = config_.sensors[i].mux_channel;
    uint8_t after = I2cTransfer::kNoDependency;
    const MuxWrite write = MuxWriteBefore(ch, uses_mux, &channel);
    if (write == MuxWrite::kAllOff) {  // (the last batch's channel may be on too)
      b.transfers[n++] =
          I2cTransfer{kMuxAddress,  drivers::tca9548a::kNone, 0, I2cTransfer::kNoDependency,
                      &b.buf[i][0], drivers::I2cStatus::kOk};
    } else if (write == MuxWrite::kSelect) {
      // Select (and, on its turn, read back the control register in the same transaction as
      // Tca9548a::Select does: StartBatch sets n).
      b.transfers[n] =
          I2cTransfer{kMuxAddress,  static_cast<uint8_t>(1u << ch), 1, I2cTransfer::kNoDependency,
                      &b.buf[i][0], drivers::I2cStatus::kOk};
      b.select[b.selects++] = n;
      select = n++;
    }
    if (ch < drivers::tca9548a::kChannels) after = select;
    b.transfers[n] = I2cTransfer{t.addr7, t.reg, t.n, after, &b.buf[i][1], drivers::I2cStatus::kOk};
    b.read[i] = &b.transfers[n++];
  }
  b.count = n;
}

App::SampleBatch* App::FinishBatch() {
  if (!batch_pending_) return nullptr;
  batch_pending_ = false;
  SampleBatch& b = batches_[batch_next_ ^ 1];
  if (b.count != 0) hal_.batch->Wait();
  return &b;
}

void App::CollectPendingBatch() {
  const SampleBatch* done = FinishBatch();
  if (done != nullptr) CollectBatch(*done);
}

void App::CollectBatch(const SampleBatch& b) {
  Mark(activity::kCalibration);
  bool nack = false;
  // Walked with pointers (slot i's sensor and transfer): indexing 8-byte transfers and
  // 100-byte sensors by i costs a multiplication each on the AVR.
  Sensor* s = sensors_;
  I2cTransfer* const* read = b.read;
  for (uint8_t i = 0; i < config_.sensor_count; ++i, ++s, ++read) {
    const I2cTransfer* r = *read;
    if (r == nullptr) {
      s->Sample(loop_periods_);  // not read (unbound, not configured): clears `fresh`
    } else {
      drivers::I2cStatus st = r->status;
      if (r->after != I2cTransfer::kNoDependency) {
        // The channel select must have been acknowledged, and read back when it was its turn.
        const I2cTransfer& sel = b.transfers[r->after];
        if (sel.status != drivers::I2cStatus::kOk || (sel.n != 0 && sel.buf[0] != sel.reg)) {
          st = drivers::I2cStatus::kBusError;
        }
      }
      s->CompleteSample(st, r->buf, loop_periods_);
    }
    nack = nack || s->nacked();
  }
  if (nack) mux_.Invalidate();
  Mark(activity::kOther);
}

void App::StepFilter(uint8_t periods) {
  namespace fh = proto::filter_health;
  overflow_ = false;
  const uint8_t kind = config_.filter.kind;
  if (!filter_valid_ || kind == static_cast<uint8_t>(proto::FilterKind::kOff)) {
    health_ = 0;
    return;
  }
  FilterAccel* const acc = filter_acc_;
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) {
      const Sensor* s = chosen_sensor_[l][k];
      if (s == nullptr) break;  // the chosen come first; the unused slots are never read
      const LinkReading& r = s->reading();
      acc[l](2 * k) = FilterPolicy::Accel::FromRaw(r.x_q16);
      acc[l](2 * k + 1) = FilterPolicy::Accel::FromRaw(r.y_q16);
    }
  }
  Mark(activity::kFilter);
  if (kind == static_cast<uint8_t>(proto::FilterKind::kAnalytical)) {
    StepAnalytical(acc[0], acc[1]);
  } else {
    core::Step<FilterPolicy, kFilterSensorsPerLink>(filter_settings_, acc[0], acc[1], filter_,
                                                    periods);
  }
  Mark(activity::kOther);
  uint8_t h = fh::kRunning;
  const uint32_t startup_steps = kStartupSeconds * static_cast<uint32_t>(config_.rate_hz);
  if (filter_.health.steps <= startup_steps) h |= fh::kStartup;
  if (filter_.health.steps == 1) h |= fh::kReset;
  if (filter_.health.saturations != 0) h |= fh::kSaturated;
  if (filter_.health.skipped_updates != 0) h |= fh::kDiverged;
  for (int l = 0; l < 2; ++l) {
    for (int k = 0; k < kFilterSensorsPerLink; ++k) {
      const Sensor* s = chosen_sensor_[l][k];
      if (s != nullptr && s->calibration_saturated()) overflow_ = true;
    }
  }
  if (overflow_) h |= fh::kOverflow;
  health_ = h;
}

void App::StepAnalytical(const FilterAccel& acc_a, const FilterAccel& acc_b) {
  // Filter kind analytical streams eq. 12 only (APP.md): core::AnalyticalTerms, the first lines
  // of core::Step, so the streamed angle is the very value the full step's state gives:
  //   z^a = F^a a^a, u = F^b a^b (eq. 8);  theta = atan2(z1 u2 - z2 u1, z1 u1 + z2 u2) (eq. 12).
  // The EKF's state is left alone (SelectFilterSensors resets it when the kind changes).
  const uint16_t saturations_before = core::SaturationCount();
  core::AnalyticalTerms(filter_settings_, acc_a, acc_b, filter_);
  filter_.health.saturations = static_cast<uint16_t>(
      filter_.health.saturations + (core::SaturationCount() - saturations_before));
  ++filter_.health.steps;
}

uint8_t App::SensorStatusMask() const {
  uint8_t any = 0;
  for (uint8_t i = 0; i < config_.sensor_count; ++i) any |= sensors_[i].status();
  return any;
}

void App::Stream(uint32_t now_us) {
  if (stream_mode_ == 0) return;
  const bool analytical =
      config_.filter.kind == static_cast<uint8_t>(proto::FilterKind::kAnalytical);
  const bool running = (health_ & proto::filter_health::kRunning) != 0;
  const int32_t theta =
      !running ? 0
               : core::ConvertFixed<24>(analytical ? core::AnalyticalAngleOf(filter_)
                                                   : core::OutputAngle(filter_settings_, filter_))
                     .raw();
  const int32_t omega_a =
      running && !analytical ? core::ConvertFixed<16>(filter_.omega(0)).raw() : 0;
  const int32_t omega_b =
      running && !analytical ? core::ConvertFixed<16>(filter_.omega(1)).raw() : 0;
  // Status first when due (periodically, StreamMode.status, and whenever a sensor's fault bits
  // change): on a saturated link it takes the room and this loop's sample frame is the one
  // dropped; behind the sample frame it would almost never fit.
  // Each sensor's status once (the fault check here, the sample frame below).
  uint8_t status[kMaxSensors];
  bool changed = false;
  {
    const Sensor* s = sensors_;
    for (uint8_t i = 0; i < config_.sensor_count; ++i, ++s) {
      status[i] = s->status();
      if ((status[i] & kFaultBits) != last_status_mask_[i]) changed = true;
    }
  }
  const bool periodic = (stream_mode_ & proto::stream_mode::kStatus) && status_interval_us_ != 0 &&
                        Due(now_us, last_status_us_, status_interval_us_);
  // A due status that did not fit holds back this loop's frames (dropped and counted as any
  // frame without room): otherwise, on a link the stream saturates, the room each loop frees
  // goes to the per-loop frame whenever that is the smaller (lean_estimate, 27 bytes) and the
  // status never fits again.
  struct ReleaseRoom {
    uint8_t& room;
    ~ReleaseRoom() { room = 0; }
  } release{status_room_};
  if ((changed || periodic) && !SendStatus(now_us)) {
    status_room_ = static_cast<uint8_t>(kStatusRoom);
  }
  // The per-loop messages every stream_every_-th loop (start_stream's `every`).
  if (--stream_countdown_ != 0) return;
  stream_countdown_ = stream_every_;
  if (stream_mode_ & proto::stream_mode::kLeanEstimate) {
    proto::LeanEstimate m;
    m.theta = theta;
    m.omega_a = omega_a;
    m.omega_b = omega_b;
    m.health = health_;
    m.faulty = 0;
    for (uint8_t i = 0; i < config_.sensor_count; ++i) {
      if (status[i] & kFaultBits) m.faulty = static_cast<uint16_t>(m.faulty | (1u << i));
    }
    Send(m, now_us, true);
  }
  if (stream_mode_ & proto::stream_mode::kSampleEstimate) {
    // The high-rate frame, written field by field straight into the frame buffer (the layout of
    // the generated proto::SampleEstimate::encode; test_app_streaming decodes it with the
    // generated decoder): no 190-byte message struct filled and copied every loop.
    using SampleMsg = proto::SampleEstimate;
    uint8_t* p = tx_ + proto::kPayloadOffset;
    const uint8_t count = config_.sensor_count;
    proto::put_i32(p + 0, theta);
    proto::put_i32(p + 4, omega_a);
    proto::put_i32(p + 8, omega_b);
    p[12] = health_;
    p[13] = count;
    p += SampleMsg::kFixedSize + 1;
    const Sensor* s = sensors_;
    for (uint8_t i = 0; i < count; ++i, ++s, p += SampleMsg::kItemSize) {
      const drivers::RawSample& c = s->counts();
      proto::put_i24(p + 0, c.x);
      proto::put_i24(p + 3, c.y);
      proto::put_i24(p + 6, c.z);
      p[9] = s->fresh();
      p[10] = status[i];
    }
    SendPayload(SampleMsg::kId,
                SampleMsg::kFixedSize + 1 + static_cast<size_t>(count) * SampleMsg::kItemSize,
                now_us, true);
  }
  if (stream_mode_ & proto::stream_mode::kSamples) {
    proto::Samples m;
    m.sensors_count = config_.sensor_count;
    for (uint8_t i = 0; i < config_.sensor_count; ++i) {
      const Sensor& s = sensors_[i];
      m.sensors[i].x = s.counts().x;
      m.sensors[i].y = s.counts().y;
      m.sensors[i].z = s.counts().z;
      m.sensors[i].fresh = s.fresh();
      m.sensors[i].status = s.status();
    }
    Send(m, now_us, true);
  }
  if (stream_mode_ & proto::stream_mode::kEstimate) {
    proto::Estimate m;
    m.theta = theta;
    m.omega_a = omega_a;
    m.omega_b = omega_b;
    m.theta_analytical =
        running ? core::ConvertFixed<24>(core::AnalyticalAngleOf(filter_)).raw() : 0;
    m.nis = 0;  // not exposed by the filter (FILTER.md "Health")
    const int32_t trace = core::ConvertFixed<16>(core::CovarianceTrace(filter_)).raw();
    m.p_trace = running && trace > 0 ? static_cast<uint32_t>(trace) : 0;
    m.saturations = filter_.health.saturations;
    m.overflows = filter_.health.skipped_updates;
    m.health = health_;
    Send(m, now_us, true);
  }
}

bool App::SendStatus(uint32_t now_us) {
  proto::Status m;
  m.uptime_ms = uptime_ms_;
  m.loop_overruns = overruns_;
  m.uart_drops = uart_drops_;
  m.loop_rate_hz = loop_rate_hz_;
  m.idle_permille = idle_permille_;
  m.sustainable_rate_hz = sustainable_rate_hz_;
  m.eeprom = eeprom_state_;
  m.stream_mode = stream_mode_;
  const proto::DecoderStats& st = rx_.stats();
  m.rx_errors = AddSaturating16(0, st.crc_errors + st.malformed + st.oversize + st.version_errors);
  m.sensors_count = config_.sensor_count;
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    const Sensor& s = sensors_[i];
    m.sensors[i].nacks = s.nacks();
    m.sensors[i].id_errors = s.id_errors();
    m.sensors[i].saturations = s.saturations();
    m.sensors[i].freezes = s.freezes();
    m.sensors[i].status = s.status();
  }
  // Dropped for lack of room: neither the interval nor the reported faults advance, so the
  // next loop tries again.
  if (!Send(m, now_us, true)) return false;
  last_status_us_ = now_us;
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    last_status_mask_[i] = sensors_[i].status() & kFaultBits;
  }
  return true;
}

void App::SendHello() {
  proto::Hello m;
  m.protocol_version = proto::kProtocolVersion;
  m.schema_hash = proto::kSchemaHash;
  m.firmware_major = kFirmwareMajor;
  m.firmware_minor = kFirmwareMinor;
  m.firmware_patch = kFirmwarePatch;
  memset(m.build, 0, sizeof m.build);
  const char* id = JA_BUILD_ID;
  for (size_t i = 0; i < sizeof m.build && id[i] != '\0'; ++i) m.build[i] = id[i];
  m.board = hal_.board;
  m.sample_rate_hz = config_.rate_hz;
  m.stream_mode = stream_mode_;
  m.eeprom = eeprom_state_;
  m.sensors_count = config_.sensor_count;
  for (uint8_t i = 0; i < config_.sensor_count; ++i) {
    const SensorConfig& c = config_.sensors[i];
    m.sensors[i].link = c.link;
    m.sensors[i].model = c.model;
    m.sensors[i].mux_channel = c.mux_channel;
    m.sensors[i].address = c.address;
    m.sensors[i].chip_id = sensors_[i].chip_id();
    m.sensors[i].range_g = c.range_g;
    m.sensors[i].status = sensors_[i].status() & kFaultBits;
    m.sensors[i].read_delay_us = ReadDelayUs(i);
  }
  Send(m, hal_.clock.NowUs());
}

void App::SendLog(uint8_t level, const char* text) {
  proto::Log m;
  m.level = level;
  size_t n = strlen(text);
  if (n > sizeof m.text.data) n = sizeof m.text.data;
  memcpy(m.text.data, text, n);
  m.text.len = static_cast<uint8_t>(n);
  Send(m, hal_.clock.NowUs());
}

void App::SendAck(const proto::FrameHeader& cmd, ErrorCode error, uint16_t detail) {
  proto::Ack m;
  m.command_id = cmd.msg_id;
  m.command_seq = cmd.seq;
  m.error = static_cast<uint8_t>(error);
  m.detail = detail;
  Send(m, hal_.clock.NowUs());
}

template <class Msg>
bool App::Send(const Msg& msg, uint32_t t_us, bool stream) {
  size_t len = 0;
  if (!msg.encode(tx_ + proto::kPayloadOffset, proto::kMaxPayload, &len)) {
    ++seq_;  // as a dropped frame
    return false;
  }
  return SendPayload(Msg::kId, len, t_us, stream);
}

bool App::SendPayload(uint8_t msg_id, size_t payload_len, uint32_t t_us, bool stream) {
  const proto::FrameHeader header = {proto::kProtocolVersion, msg_id, seq_, t_us};
  // The frame's length is known before encoding (tx_ holds the longest): the room is checked
  // first, then the board frames it into its transmit buffer, or the app into tx_ + TxWrite.
  const size_t n = proto::framed_size(payload_len);
  ++seq_;  // also for a dropped frame: the host counts the gap as frames lost
  if (n == 0) return false;
  // While a command waits for room for its replies, a stream frame must leave that room; and
  // the room a due status waits for (Stream).
  size_t room = stream ? n + status_room_ : n;
  if (stream && command_waiting_) room += ReplyRoom(rx_.header().msg_id);
  if (hal_.serial.TxFree() < room) {
    uart_drops_ = AddSaturating16(uart_drops_, static_cast<uint32_t>(n));
    return false;
  }
  if (!hal_.serial.TxFrame(header, tx_, static_cast<uint16_t>(payload_len),
                           static_cast<uint16_t>(n))) {
    proto::finish_frame(header, payload_len, tx_, sizeof tx_);
    hal_.serial.TxWrite(tx_, static_cast<uint16_t>(n));
  }
  return true;
}

size_t ReplyRoom(uint8_t msg_id) {
  size_t n = proto::framed_size(proto::Ack::kMaxSize);
  if (msg_id == proto::GetInfo::kId) n += proto::framed_size(proto::Hello::kMaxSize);
  if (msg_id == proto::GetCalibration::kId) n += proto::framed_size(proto::Calibration::kMaxSize);
  return n;
}

void App::HandleCommandFrame() {
  // Commands run with the bus idle (they may probe, or write the settings' flash sector), but
  // the finished batch's samples are left to the next loop, which stays on its grid; one that
  // rebinds a sensor takes them first (BindSensor). (Collecting here and restarting the reads
  // after the command put the next batch off the grid, up to a whole batch late: ~9 overruns
  // after each start_stream at 1 kHz on the Pico.)
  if (batch_pending_) hal_.batch->Wait();
  HandleFrame();
}

void App::HandleFrame() {
  Mark(activity::kCommand);
  const proto::FrameHeader h = rx_.header();
  bool ack_sent = false;
  const ErrorCode e = HandleCommand(h, rx_.payload(), rx_.payload_size(), &ack_sent);
  if (!ack_sent) SendAck(h, e);
  Mark(activity::kOther);
}

ErrorCode App::HandleCommand(const proto::FrameHeader& h, const uint8_t* p, size_t n,
                             bool* ack_sent) {
  const bool streaming = stream_mode_ != 0;
  switch (h.msg_id) {
    case proto::GetInfo::kId: {
      proto::GetInfo m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      SendHello();
      return ErrorCode::kOk;
    }
    case proto::StartStream::kId: {
      proto::StartStream m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.mode == 0 || (m.mode & ~kKnownStreamBits) != 0 || m.every == 0) {
        return ErrorCode::kBadValue;
      }
      stream_mode_ = m.mode;
      stream_every_ = m.every;
      stream_countdown_ = 1;  // the first loop after the ack sends
      status_interval_us_ = static_cast<uint32_t>(m.status_interval_ms) * 1000u;
      // Acknowledge first, then a status frame so the host starts from the current faults.
      SendAck(h, ErrorCode::kOk);
      *ack_sent = true;
      SendStatus(hal_.clock.NowUs());
      return ErrorCode::kOk;
    }
    case proto::StopStream::kId: {
      proto::StopStream m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      stream_mode_ = 0;
      return ErrorCode::kOk;
    }
    case proto::SetRate::kId: {
      proto::SetRate m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (streaming) return ErrorCode::kNotAllowedWhileStreaming;
      if (m.rate_hz < kMinRateHz || m.rate_hz > kMaxRateHz || m.force > 1) {
        return ErrorCode::kBadValue;
      }
      // What it holds: measured, or before the first measurement what the bus holds.
      const uint16_t held = sustainable_rate_hz_ != 0 ? sustainable_rate_hz_ : bus_rate_hz_;
      if (m.force == 0 && held != 0 && m.rate_hz > held) {
        SendAck(h, ErrorCode::kRateNotSustainable, held);  // names what it holds
        *ack_sent = true;
        return ErrorCode::kRateNotSustainable;
      }
      config_.rate_hz = m.rate_hz;
      BindAllSensors();  // output data rates follow the loop rate
      SelectFilterSensors(true);
      ResetTiming();
      return ErrorCode::kOk;
    }
    case proto::SetJoint::kId: {
      proto::SetJoint m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (streaming) return ErrorCode::kNotAllowedWhileStreaming;
      if (m.link > 1 || m.x > kMaxCoordinateUm || m.x < -kMaxCoordinateUm ||
          m.y > kMaxCoordinateUm || m.y < -kMaxCoordinateUm) {
        return ErrorCode::kBadValue;
      }
      config_.joint_um[m.link][0] = m.x;
      config_.joint_um[m.link][1] = m.y;
      SelectFilterSensors(true);
      return ErrorCode::kOk;
    }
    case proto::SetSensor::kId: {
      proto::SetSensor m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (streaming) return ErrorCode::kNotAllowedWhileStreaming;
      if (m.count > kMaxSensors && m.count <= proto::kMaxSensors) return ErrorCode::kUnsupported;
      if (m.count == 0 || m.count > kMaxSensors || m.slot >= m.count) return ErrorCode::kBadValue;
      SensorConfig s;
      s.link = m.link;
      s.model = m.model;
      s.mux_channel = m.mux_channel;
      s.address = m.address;
      s.range_g = m.range_g;
      s.x_um = m.x;
      s.y_um = m.y;
      s.rotation_urad = m.rotation;
      if (!IsValidSensor(s)) return ErrorCode::kBadValue;
      const uint8_t old_count = config_.sensor_count;
      config_.sensors[m.slot] = s;
      config_.sensor_count = m.count;
      BindSensor(m.slot);
      for (uint8_t i = m.count; i < old_count; ++i) BindSensor(i);  // slots dropped
      for (uint8_t i = old_count; i < m.count; ++i) {
        if (i != m.slot && IsValidSensor(config_.sensors[i])) BindSensor(i);
      }
      UpdateBusRate();
      SelectFilterSensors(true);
      return ErrorCode::kOk;
    }
    case proto::SetCalibration::kId: {
      proto::SetCalibration m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.slot >= config_.sensor_count) return ErrorCode::kBadValue;
      const int32_t s[9] = {m.s00, m.s01, m.s02, m.s10, m.s11, m.s12, m.s20, m.s21, m.s22};
      const int32_t o[3] = {m.ox, m.oy, m.oz};
      if (!IsPlausibleCalibration(s, o)) return ErrorCode::kBadCalibration;
      Calibration& k = config_.calibration[m.slot];
      memcpy(k.s_q24, s, sizeof s);
      k.o_umps2[0] = m.ox;
      k.o_umps2[1] = m.oy;
      k.o_umps2[2] = m.oz;
      sensors_[m.slot].SetCalibration(config_.sensors[m.slot], k);
      SelectFilterSensors(true);  // the readings jump: start the filter afresh
      return ErrorCode::kOk;
    }
    case proto::SetFilter::kId: {
      proto::SetFilter m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.kind > static_cast<uint8_t>(proto::FilterKind::kOff) || m.flags != 0) {
        return ErrorCode::kBadValue;
      }
      if (m.p0 != 0 && m.p0 != 65536u) return ErrorCode::kUnsupported;
      if (m.accel_sigma != 0 &&
          (m.accel_sigma < kMinAccelSigmaU || m.accel_sigma > kMaxAccelSigmaU)) {
        return ErrorCode::kBadNoise;
      }
      config_.filter.kind = m.kind;
      config_.filter.accel_sigma_u = m.accel_sigma;
      config_.filter.p0_q16 = m.p0;
      config_.filter.flags = m.flags;
      SelectFilterSensors(true);
      return ErrorCode::kOk;
    }
    case proto::RestartFilter::kId: {
      proto::RestartFilter m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      // The settings as they are: a changed choice of sensors reconfigures (and resets); with
      // the same sensors and settings their Configure stands and only the state starts again.
      // (A Configure here, ~3 ms of float on the AVR, made the loop of every `live`/`record`
      // stream start miss two periods at 250 Hz.)
      const uint16_t resets = filter_resets_;
      SelectFilterSensors(false);
      if (filter_resets_ == resets) {
        core::Reset(filter_);
        filter_resets_ = AddSaturating16(filter_resets_, 1);
      }
      return ErrorCode::kOk;
    }
    case proto::SaveEeprom::kId: {
      proto::SaveEeprom m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.confirm != kSaveConfirm) return ErrorCode::kBadValue;
      if (streaming) return ErrorCode::kNotAllowedWhileStreaming;  // writes block for ~2 s on AVR
      const bool saved = SaveConfig(hal_.eeprom, config_);
      ResetTiming();  // the writes took time, failed or not; do not count them as overruns
      if (!saved) return ErrorCode::kEepromFailed;
      eeprom_state_ = static_cast<uint8_t>(proto::EepromState::kOk);
      return ErrorCode::kOk;
    }
    case proto::Reset::kId: {
      proto::Reset m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.kind > static_cast<uint8_t>(proto::ResetKind::kFactoryDefaults)) {
        return ErrorCode::kBadValue;
      }
      factory_reset_pending_ = m.kind == static_cast<uint8_t>(proto::ResetKind::kFactoryDefaults);
      restart_pending_ = true;  // after the ack has been queued (next Poll)
      return ErrorCode::kOk;
    }
    case proto::GetCalibration::kId: {
      proto::GetCalibration m;
      if (!m.decode(p, n)) return ErrorCode::kBadLength;
      if (m.slot >= config_.sensor_count ||
          m.source > static_cast<uint8_t>(proto::CalibrationSource::kEeprom)) {
        return ErrorCode::kBadValue;
      }
      Calibration k = config_.calibration[m.slot];
      if (m.source == static_cast<uint8_t>(proto::CalibrationSource::kEeprom) &&
          !ReadStoredCalibration(hal_.eeprom, m.slot, &k)) {
        return ErrorCode::kEepromFailed;
      }
      proto::Calibration r;
      r.slot = m.slot;
      r.source = m.source;
      r.s00 = k.s_q24[0];
      r.s01 = k.s_q24[1];
      r.s02 = k.s_q24[2];
      r.s10 = k.s_q24[3];
      r.s11 = k.s_q24[4];
      r.s12 = k.s_q24[5];
      r.s20 = k.s_q24[6];
      r.s21 = k.s_q24[7];
      r.s22 = k.s_q24[8];
      r.ox = k.o_umps2[0];
      r.oy = k.o_umps2[1];
      r.oz = k.o_umps2[2];
      Send(r, hal_.clock.NowUs());
      return ErrorCode::kOk;
    }
    default:
      return ErrorCode::kUnknownCommand;
  }
}

}  // namespace app
}  // namespace ja
