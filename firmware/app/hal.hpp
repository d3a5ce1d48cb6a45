// The hardware the application needs, as small interfaces injected into ja::app::App (the
// caller owns the hardware; the app never names a platform). Each board implements
// them once: the AVR board (Timer, USART with a TX ring drained by its ISR, avr-libc EEPROM,
// watchdog reset), the native virtual board (simulated clock, pty, a file as EEPROM) and the
// tests' fakes (firmware/tests/app/app_fakes.hpp). The I2C bus and the millisecond delay are the
// drivers' own interfaces (drivers/i2c_bus.hpp).
#pragma once

#include <stdint.h>

#include "drivers/i2c_bus.hpp"
#include "protocol/frame.hpp"

namespace ja {
namespace app {

/// Free-running microsecond clock; wraps after 2^32 us (~71.6 min). The app only ever takes
/// differences of readings, so wrapping is harmless.
class Clock {
 public:
  virtual uint32_t NowUs() = 0;

 protected:
  ~Clock() = default;
};

/// The serial port. Transmit goes into a bounded buffer that the platform drains at the baud
/// rate; the app asks for room first and drops (and counts) a whole frame that does not fit, so
/// the host never sees half a frame. Receive is polled one byte at a time.
class SerialPort {
 public:
  /// Bytes the transmit buffer can take right now.
  virtual uint16_t TxFree() = 0;
  /// Queues n bytes; the app guarantees n <= TxFree().
  virtual void TxWrite(const uint8_t* data, uint16_t n) = 0;
  /// The next received byte (0..255), or -1 when none is waiting.
  virtual int16_t RxRead() = 0;
  /// Optional: frames the payload at frame + proto::kPayloadOffset (proto::finish_frame's bytes,
  /// n of them, n <= TxFree()) straight into the transmit buffer and returns true. false (the
  /// default): not offered; the app frames into its buffer and calls TxWrite. The AVR board
  /// encodes into its ring (proto::finish_frame_to_ring): no copy of the encoded frame.
  virtual bool TxFrame(const proto::FrameHeader& header, uint8_t* frame, uint16_t payload_len,
                       uint16_t n) {
    (void)header;
    (void)frame;
    (void)payload_len;
    (void)n;
    return false;
  }

 protected:
  ~SerialPort() = default;
};

/// Byte-addressed non-volatile store (the ATmega2560 has 4 KB of EEPROM; the Pico a flash
/// sector). Writes may be slow (3.3 ms per byte on the AVR): the app writes only on an explicit
/// save_eeprom command or a factory reset.
class Eeprom {
 public:
  virtual uint16_t Size() = 0;
  virtual uint8_t Read(uint16_t addr) = 0;
  virtual void Write(uint16_t addr, uint8_t value) = 0;
  /// Makes the writes since the last Commit permanent; false if that failed. A store that
  /// writes whole sectors (the Pico's flash) may stage Write() until then, and Read() shows
  /// the stored bytes: the app calls Commit after its writes, before reading them back.
  /// Default: every Write is permanent at once.
  virtual bool Commit() { return true; }

 protected:
  ~Eeprom() = default;
};

/// What the app asks of the system beyond I/O.
class System {
 public:
  /// Restart the firmware (AVR: watchdog reset). A board that cannot reboot may call
  /// App::Begin() again from its main loop instead; the app calls this from Poll() only after
  /// the reset command's ack has been queued.
  virtual void Reboot() = 0;

 protected:
  ~System() = default;
};

/// One transfer of an asynchronous batch: write `reg`, repeated START, read `n` bytes into `buf`,
/// STOP; with n = 0 only `reg` is written, then STOP. A TCA9548A select is a write of the channel
/// mask as `reg`, a select-and-verify the same with a 1-byte read-back (drivers/tca9548a.hpp),
/// so a batch of sensor reads is a list of these.
struct I2cTransfer {
  static constexpr uint8_t kNoDependency = 0xFF;
  uint8_t addr7;
  uint8_t reg;
  uint8_t n;
  /// Index of an earlier transfer that must have succeeded (the mux select in front of a
  /// sensor read); otherwise this one is skipped with kBusError. kNoDependency: always runs.
  uint8_t after;
  uint8_t* buf;
  drivers::I2cStatus status;  // set by the batch when the transfer has finished
};

/// Runs a list of transfers in the background (AVR: the TWI interrupt walks the list while the
/// CPU filters the previous loop's samples). Optional: a board without it leaves Hal::batch
/// null and the app reads its sensors through `i2c` synchronously (APP.md, "The loop").
/// A board must not start a blocking I2cBus transfer while a batch runs (it waits for the batch).
class I2cBatch {
 public:
  /// Starts the transfers in order; returns at once or after finishing them. `t` must stay
  /// valid until Wait() returned.
  virtual void Start(I2cTransfer* t, uint8_t count) = 0;
  /// Returns once every transfer of the last Start has its status (or has timed out:
  /// kTimeout). Everything the transfers wrote is visible to the caller afterwards.
  virtual void Wait() = 0;

 protected:
  ~I2cBatch() = default;
};

/// What the CPU works on, for the cycle harness's loop budget (AVR: the id goes to GPIOR1 and
/// interrupts save and restore it; issue 6). Optional (Hal::activity may be null).
namespace activity {
constexpr uint8_t kOther = 0;        // main loop, waiting, statistics
constexpr uint8_t kTwiIsr = 1;       // board interrupts (listed for completeness)
constexpr uint8_t kUartIsr = 2;      //
constexpr uint8_t kFilter = 3;       // core::Step
constexpr uint8_t kCalibration = 4;  // sample bookkeeping + calibration map
constexpr uint8_t kFraming = 5;      // message encoding, CRC, COBS, queueing
constexpr uint8_t kTimerIsr = 6;     //
constexpr uint8_t kCommand = 7;      // command decoding and handling
}  // namespace activity

class ActivityMarker {
 public:
  virtual void Mark(uint8_t id) = 0;

 protected:
  ~ActivityMarker() = default;
};

/// Everything a board injects. References and pointers must outlive the App.
/// A constructor, not an aggregate with default member initialisers: those are no aggregate
/// before C++14, and the Arduino AVR core compiles sketches and libraries as gnu++11.
struct Hal {
  Hal(drivers::I2cBus& i2c_bus, drivers::Delay& delay_source, Clock& clock_source,
      SerialPort& serial_port, Eeprom& eeprom_store, System& system_control, uint8_t board_id,
      I2cBatch* sample_batch = nullptr, ActivityMarker* activity_marker = nullptr,
      uint16_t factory_rate = 0, uint16_t busy_scale = 0, uint16_t sample_byte_ns = 0,
      uint16_t scl_ns = 0)
      : i2c(i2c_bus),
        delay(delay_source),
        clock(clock_source),
        serial(serial_port),
        eeprom(eeprom_store),
        system(system_control),
        board(board_id),
        batch(sample_batch),
        activity(activity_marker),
        factory_rate_hz(factory_rate),
        busy_scale_permille(busy_scale),
        bus_byte_ns(sample_byte_ns),
        scl_period_ns(scl_ns) {}

  drivers::I2cBus& i2c;  // the upstream bus (the TCA9548A sits on it)
  drivers::Delay& delay;
  Clock& clock;
  SerialPort& serial;
  Eeprom& eeprom;
  System& system;
  uint8_t board;             // proto::Board, reported in hello
  I2cBatch* batch;           // steady-state sample reads in the background, optional
  ActivityMarker* activity;  // cycle accounting, optional
  // The rate a fresh EEPROM boots at: one the board holds with its factory sensors at >= 20 %
  // asleep (measured per board, README); 0 = kFactoryRateHz.
  uint16_t factory_rate_hz;
  // Work a loop's own timing does not see, as a factor on its busy time (per mille; 0 = 1000):
  // interrupts that run while the board waits (the Mega's background TWI reads and UART
  // transmit), measured per board against the cycle-exact sleep count (docs/measurements.md).
  uint16_t busy_scale_permille;
  // How long one byte of the sample reads takes on the bus, interrupt included, ns: the board
  // reads its sensors one after another, so each is sampled later than the first
  // (App::ReadDelayUs; the filter turns the readings back to the row's time). 0 = reads take no
  // time (a simulated bus whose sensors all sample at the row's time).
  uint16_t bus_byte_ns;
  // One SCL period of the sample batch on this board's bus, ns, stretches by its interrupts
  // included: the sustainable rate is also bounded by the bus (a loop's SCL periods times this
  // within kSustainableBusNs of a second; APP.md "Commands"). 0 = no bus bound (a simulated
  // bus that takes no time).
  uint16_t scl_period_ns;
};

}  // namespace app
}  // namespace ja
