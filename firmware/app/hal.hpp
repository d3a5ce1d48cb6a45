// The hardware the application needs, as small interfaces injected into ja::app::App (STYLE.md
// section 2: the caller owns the hardware; the app never names a platform). Each board implements
// them once: the AVR board (Timer, USART with a TX ring drained by its ISR, avr-libc EEPROM,
// watchdog reset), the native virtual board (simulated clock, pty, a file as EEPROM) and the
// tests' fakes (firmware/tests/app/app_fakes.hpp). The I2C bus and the millisecond delay are the
// drivers' own interfaces (drivers/i2c_bus.hpp).
#pragma once

#include <stdint.h>

#include "drivers/i2c_bus.hpp"

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

 protected:
  ~SerialPort() = default;
};

/// Byte-addressed non-volatile store (the ATmega2560 has 4 KB of EEPROM). Writes may be slow
/// (3.3 ms per byte on the AVR): the app writes only on an explicit save_eeprom command.
class Eeprom {
 public:
  virtual uint16_t Size() = 0;
  virtual uint8_t Read(uint16_t addr) = 0;
  virtual void Write(uint16_t addr, uint8_t value) = 0;

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

/// Everything a board injects. References must outlive the App.
struct Hal {
  drivers::I2cBus& i2c;  // the upstream bus (the TCA9548A sits on it)
  drivers::Delay& delay;
  Clock& clock;
  SerialPort& serial;
  Eeprom& eeprom;
  System& system;
  uint8_t board;  // proto::Board, reported in hello
};

}  // namespace app
}  // namespace ja
