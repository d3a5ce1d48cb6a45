// The firmware application (issue 4, item 4): a fixed-rate loop that samples every configured
// sensor through the drivers (TCA9548A channels as bus decorators), applies each sensor's
// calibration and mounting rotation in fixed point, steps the joint filter (FixedPolicy), streams
// framed sample+estimate and status frames, answers commands with acks, keeps its configuration
// in EEPROM (layout version + CRC) and flags per-sensor faults while it keeps running.
// Portable C++14: all hardware comes in through Hal (app/hal.hpp). No allocation after Begin().
// Behaviour, timing and the EEPROM layout are documented in APP.md next to this file.
#pragma once

#include <stddef.h>
#include <stdint.h>

#include "app/app_config.hpp"
#include "app/hal.hpp"
#include "app/sensor.hpp"
#include "core/joint_filter.hpp"
#include "drivers/tca9548a.hpp"
#include "protocol/frame.hpp"

namespace ja {
namespace app {

constexpr uint8_t kFirmwareMajor = 0;
constexpr uint8_t kFirmwareMinor = 1;
constexpr uint8_t kFirmwarePatch = 0;
#ifndef JA_BUILD_ID
#define JA_BUILD_ID "dev"
#endif
constexpr uint8_t kMuxAddress = drivers::tca9548a::kBaseAddress;  // TCA9548A at 0x70
constexpr uint32_t kProbeIntervalUs = 250000;    // re-probe one faulted sensor this often
constexpr uint32_t kIdCheckIntervalUs = 100000;  // re-read one working sensor's ID this often
constexpr uint32_t kStatsWindowUs = 1000000;     // loop rate and idle fraction window
constexpr uint32_t kSustainableBusyUs =
    800000;  // a rate held at >= 20 % asleep: 0.8 s of work a second
// ... and with the bus's SCL periods within 96 % of it (Hal::scl_period_ns): the rest covers the
// wake-up before a loop starts its batch, the gaps between transfers and the loop with an ID
// check. Measured on sim://pico (APP.md "Commands"): rigs held up to 96.8-97.2 % and slipped
// from 97.5 %.
constexpr uint32_t kSustainableBusNs = 960000000;
// A multiplexer that acknowledges a select without switching feeds the filter another channel's
// sensor for at most this long before that sensor is flagged (SelectReadBackEvery).
constexpr uint32_t kSelectVerifyUs = 8000;
constexpr uint16_t kSaveConfirm = 0x5AFE;  // save_eeprom.confirm
constexpr uint16_t kBootWaitMs = 700;  // BNO055 ready ~650 ms after reset (docs/sensors.md §A3)
constexpr uint16_t kBootRetryMs = 50;
constexpr uint32_t kStartupSeconds = 2;  // FilterHealth.startup after a (re)initialisation

using FilterPolicy = core::FixedPolicy;
/// Transmit-buffer room a command waits for before it is handled: its replies (ReplyRoom: the
/// ack, plus hello for get_info and the calibration for get_calibration). Meanwhile a stream
/// frame goes only if it leaves that room, so on a link the stream saturates the buffer drains
/// and the stream loses its own frames, never a reply ("one ack per command").
size_t ReplyRoom(uint8_t msg_id);
/// The room a due status waits for (the longest status frame).
constexpr size_t kStatusRoom = proto::framed_size(proto::Status::kMaxSize);
static_assert(kStatusRoom <= 255, "status_room_ is a byte");
constexpr uint32_t kReplyWaitUs = 500;       // how often a waiting command looks for room
constexpr uint32_t kReplyWaitMaxUs = 20000;  // then it is handled anyway
// The filter uses the first usable sensors of each link, at least two and at most this many.
constexpr int kFilterSensorsPerLink = core::kMaxSensorsPerLink;
constexpr int kFilterMinSensorsPerLink = 2;

/// Sample periods between two loops whose grid slots are gap_us apart: round(gap / period),
/// clamped to 1..core::kMaxStepPeriods (APP.md "Timing"; the host's mirror derives the same
/// from consecutive frames' t_us, jointangle.estimators.mirror.step_periods). Without a division:
/// at most kMaxStepPeriods compare-and-subtract passes.
inline uint8_t StepPeriods(uint32_t gap_us, uint32_t period_us) {
  if (gap_us >= static_cast<uint32_t>(core::kMaxStepPeriods) * period_us) {
    return core::kMaxStepPeriods;
  }
  uint32_t rest = gap_us + period_us / 2u;  // floor(rest / period), at least 1
  uint8_t n = 1;
  while (n < core::kMaxStepPeriods && rest >= 2u * period_us) {
    rest -= period_us;
    ++n;
  }
  return n;
}

/// A loop's multiplexer selects are written without reading them back except one, in turn,
/// every this many loops: each channel's selection is then verified within kSelectVerifyUs
/// (or every `selects` loops, when that is longer). 1 at the rates the Mega runs; at 1 kHz with
/// two selects a loop 4, which saves 19 SCL periods in three loops of four (APP.md "Pipelined
/// sampling").
inline uint8_t SelectReadBackEvery(uint8_t selects, uint32_t period_us) {
  if (selects == 0 || period_us == 0) return 1;
  const uint32_t every = kSelectVerifyUs / (static_cast<uint32_t>(selects) * period_us);
  return every < 1 ? 1 : every > 255 ? 255 : static_cast<uint8_t>(every);
}

class App {
 public:
  explicit App(const Hal& hal);
  App(const App&) = delete;
  App& operator=(const App&) = delete;

  /// Start-up (and soft restart): loads the configuration from EEPROM, probes every sensor,
  /// configures the filter and sends hello (seq 0) — plus a log line when EEPROM was bad.
  void Begin();
  /// Call as often as possible: handles received bytes, and runs one loop when it is due.
  /// Returns the microseconds until the next loop is due (0 = call again now), so a board can
  /// sleep that long (or until a byte arrives).
  uint32_t Poll();

  // ---- Observation (tests, boards) ----
  const Config& config() const { return config_; }
  uint8_t eeprom_state() const { return eeprom_state_; }
  uint8_t stream_mode() const { return stream_mode_; }
  uint16_t loop_overruns() const { return overruns_; }
  uint16_t uart_drops() const { return uart_drops_; }
  uint32_t loops() const { return loops_; }
  uint16_t seq() const { return seq_; }
  const Sensor& sensor(uint8_t i) const { return sensors_[i]; }
  bool filter_valid() const { return filter_valid_; }
  uint8_t health() const { return health_; }
  const core::FilterState<FilterPolicy>& filter_state() const { return filter_; }
  uint16_t filter_resets() const { return filter_resets_; }
  /// SCL periods of one loop's sample batch with every sensor read (the layout BuildBatch
  /// builds, one select read back; APP.md "Commands"), computed from the configuration.
  uint16_t LoopSclPeriods() const;
  /// SCL periods a multiplexer select's read-back adds (the repeated START, the address and the
  /// control byte; LoopSclPeriods counts one a loop).
  static constexpr uint16_t kReadBackSclPeriods = 1 + 9 * 2;

 private:
  /// One loop's sample reads (Hal::batch): the transfers, their buffers and the layout.
  struct SampleBatch {
    I2cTransfer transfers[2 * kMaxSensors];
    uint8_t buf[kMaxSensors][1 + kMaxSampleBytes];  // [0] mux read-back, [1..] the sample
    I2cTransfer* read[kMaxSensors];                 // slot -> its transfer, null = none
    uint8_t select[kMaxSensors];                    // indices of its multiplexer selects
    uint8_t count;
    uint8_t selects;
    bool layout_ok;   // matches the sensors (cleared by every BindSensor)
    uint8_t ready;    // bit i: slot i was sample_ready() when the layout was built
    uint8_t sensors;  // config_.sensor_count then
  };
  void BindSensor(uint8_t slot);
  void BindAllSensors();
  void ProbeDue(uint32_t now_us);
  /// Picks the filter's sensors; reconfigures and resets the filter when the choice changed.
  void SelectFilterSensors(bool force);
  bool ConfigureFilter();
  /// When slot `slot` is read in a loop after the first sensor, us (reported in hello): the
  /// bytes of the batch before its read (APP.md "Read times") times Hal::bus_byte_ns.
  uint16_t ReadDelayUs(uint8_t slot) const;
  /// The bus's bound on the rate (bus_rate_hz_) for the configuration's sensors, and the
  /// sustainable rate with it; called whenever the sensors' configuration changes.
  void UpdateBusRate();
  /// The batch's SCL periods with every sensor read and no select read back, and its selects.
  struct BusWork {
    uint16_t scl;
    uint8_t selects;
  };
  BusWork LoopBusWork() const;
  uint16_t FactoryRate() const {
    return hal_.factory_rate_hz != 0 ? hal_.factory_rate_hz : kFactoryRateHz;
  }
  void RunLoop(uint32_t now_us);
  /// Asynchronous sampling (Hal::batch): queues every sensor's read (with the multiplexer
  /// selects in front) on the board's batch and returns.
  void StartBatch();
  /// Fills `b`'s layout from the sensors' sample reads (StartBatch, when they changed).
  void BuildBatch(SampleBatch& b);
  /// Waits for the batch last started (normally finished long before); null when none was.
  SampleBatch* FinishBatch();
  /// Runs each sensor's Sample on a finished batch's result: freshness, faults, calibration.
  void CollectBatch(const SampleBatch& b);
  /// FinishBatch + CollectBatch: the bus idle and the samples taken (before a command).
  void CollectPendingBatch();
  void Mark(uint8_t activity_id) {
    if (hal_.activity != nullptr) hal_.activity->Mark(activity_id);
  }
  using FilterAccel = Eigen::Matrix<FilterPolicy::Accel, 2 * kFilterSensorsPerLink, 1>;
  /// periods: sample periods since the previous loop's slot (StepPeriods), for core::Step.
  void StepFilter(uint8_t periods);
  /// Filter kind analytical: eq. 12's terms into filter_ (AnalyticalAngleOf), the EKF not stepped.
  void StepAnalytical(const FilterAccel& acc_a, const FilterAccel& acc_b);
  void Stream(uint32_t now_us);
  /// False when it did not fit (it stays due).
  bool SendStatus(uint32_t now_us);
  void SendHello();
  void SendLog(uint8_t level, const char* text);
  void SendAck(const proto::FrameHeader& cmd, proto::ErrorCode error, uint16_t detail = 0);
  void HandleFrame();
  proto::ErrorCode HandleCommand(const proto::FrameHeader& h, const uint8_t* p, size_t n,
                                 bool* ack_sent);
  void ResetTiming();
  uint8_t SensorStatusMask() const;
  /// `stream`: a stream or status frame, which must leave a waiting command's ReplyRoom free;
  /// the replies to commands pass false.
  template <class Msg>
  bool Send(const Msg& msg, uint32_t t_us, bool stream = false);
  /// Frames the payload already written at tx_ + proto::kPayloadOffset and queues it whole, or
  /// drops it (counted in uart_drops) when the transmit buffer lacks room (or, for a stream
  /// frame, while a command waits for room for its replies). Uses a seq either way.
  bool SendPayload(uint8_t msg_id, size_t payload_len, uint32_t t_us, bool stream = false);
  /// Handles the decoded command (the decoder keeps it until the next byte is pushed).
  void HandleCommandFrame();

  Hal hal_;
  Config config_;
  uint8_t eeprom_state_ = 0;
  drivers::Tca9548a mux_;
  drivers::Tca9548aChannel channels_[drivers::tca9548a::kChannels];
  drivers::Tca9548aRoot root_;  // the bus with every channel off: sensors wired to it directly
  Sensor sensors_[kMaxSensors];

  // Filter.
  core::Settings<FilterPolicy, kFilterSensorsPerLink> filter_settings_;
  core::FilterState<FilterPolicy> filter_;
  int8_t chosen_[2][kFilterSensorsPerLink];  // slots feeding the filter, -1 = none
  const Sensor* chosen_sensor_[2][kFilterSensorsPerLink] = {};  // the same, null = none
  bool filter_valid_ = false;  // enough usable sensors and a valid geometry
  bool geometry_ok_ = false;
  uint8_t usable_mask_ = 0;  // bit i: slot i usable at the last choice
  uint8_t health_ = 0;
  // The filter's inputs of this loop (StepFilter). A member, not a local: Fixed's default
  // constructor zeroes 2 x 16 bytes on every construction (a byte loop on the AVR).
  FilterAccel filter_acc_[2];
  bool overflow_ = false;  // a calibration result saturated this loop
  uint16_t filter_resets_ = 0;

  // Asynchronous sampling: two batches of at most one select + one read per sensor, one on the
  // bus while the CPU processes the other's samples (APP.md "Pipelined sampling"). Each keeps
  // its own layout, so a layout rebuilt for the next batch leaves the finished one readable.
  SampleBatch batches_[2] = {};
  uint8_t batch_next_ = 0;      // the batch StartBatch fills next; the other is the last started
  bool batch_pending_ = false;  // the last started is on the bus or not yet collected
  // One select read back every read_back_every_ loops (SelectReadBackEvery), in turn.
  uint8_t read_back_every_ = 1;
  uint8_t read_back_wait_ = 0;  // loops until the next read-back
  uint8_t read_back_turn_ = 0;  // which select of the batch it is

  // Link.
  proto::FrameDecoder rx_;
  uint8_t tx_[proto::kMaxFrameBytes];
  uint16_t seq_ = 0;
  uint8_t stream_mode_ = 0;
  uint8_t stream_every_ = 1;         // the per-loop messages every Nth loop (start_stream)
  uint8_t stream_countdown_ = 1;     // loops until the next per-loop messages
  uint32_t status_interval_us_ = 0;  // start_stream's status_interval_ms, in µs (0 = off)
  uint32_t last_status_us_ = 0;
  uint8_t last_status_mask_[kMaxSensors];
  bool restart_pending_ = false;
  // A decoded command (still in rx_) waits for ReplyRoom(its id) bytes of transmit buffer.
  bool command_waiting_ = false;
  // Room this loop's remaining stream frames must leave free (Stream: a due status that did not
  // fit), so that the room builds up for it instead of going to the smaller per-loop frames.
  uint8_t status_room_ = 0;
  uint32_t command_waiting_since_us_ = 0;
  bool factory_reset_pending_ = false;

  // Timing and statistics.
  uint32_t period_us_ = 0;
  uint32_t next_due_us_ = 0;
  uint32_t last_probe_us_ = 0;
  uint8_t probe_cursor_ = 0;
  uint32_t last_id_check_us_ = 0;
  uint8_t id_cursor_ = 0;
  uint32_t last_now_us_ = 0;
  // The previous loop's grid slot (its frames' t_us; ResetTiming leaves it): the filter's step
  // predicts over the periods since then (StepPeriods), as the host reads them off the frames.
  uint32_t last_slot_us_ = 0;
  uint8_t loop_periods_ = 1;  // sample periods the current loop spans (StepPeriods)
  uint32_t uptime_ms_ = 0;
  uint32_t uptime_rem_us_ = 0;
  uint32_t window_start_us_ = 0;
  uint32_t window_busy_us_ = 0;
  uint16_t window_loops_ = 0;
  uint16_t loop_rate_hz_ = 0;
  uint16_t idle_permille_ = 0;
  // The highest rate held at >= 20 % asleep, from the last window's busy time a loop (0 = not
  // measured yet), and the one the bus holds (kSustainableBusNs; 0 = no bound, computed at
  // configuration by UpdateBusRate).
  uint16_t cpu_rate_hz_ = 0;
  uint16_t bus_rate_hz_ = 0;
  // The lower of the two once the CPU's is measured, else 0 (status sustainable_rate_hz).
  uint16_t sustainable_rate_hz_ = 0;
  // kSustainableBusyUs / busy_scale: 0.8 s of work a second over the board's busy-time factor.
  uint32_t sustain_scaled_ = kSustainableBusyUs * 1000u /
                             (hal_.busy_scale_permille != 0 ? hal_.busy_scale_permille : 1000u);
  uint32_t loops_ = 0;
  uint16_t overruns_ = 0;
  uint16_t uart_drops_ = 0;
};

}  // namespace app
}  // namespace ja
