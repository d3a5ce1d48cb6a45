#include "platform/avr/board/board.hpp"

#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>

#include <new>

#include "app/app.hpp"
#include "platform/avr/board/activity.hpp"
#include "platform/avr/board/clock.hpp"
#include "platform/avr/board/twi.hpp"
#include "platform/avr/board/uart.hpp"
#include "protocol/messages.hpp"

// After a watchdog reset the watchdog stays enabled (15 ms) with WDRF set: clear both before
// anything else runs (avr-libc's wdt.h recommendation; .init3 runs before static constructors).
extern "C" void ja_wdt_off_at_reset(void) __attribute__((naked, used, section(".init3")));
extern "C" void ja_wdt_off_at_reset(void) {
  MCUSR = 0;
  wdt_disable();
}

namespace ja {
namespace avr {

namespace {

class AvrEeprom final : public app::Eeprom {
 public:
  uint16_t Size() override { return E2END + 1; }  // 4096
  uint8_t Read(uint16_t addr) override {
    return eeprom_read_byte(reinterpret_cast<const uint8_t*>(addr));
  }
  void Write(uint16_t addr, uint8_t value) override {
    wdt_reset();  // a byte takes 3.3 ms; a whole image ~1.8 s
    eeprom_update_byte(reinterpret_cast<uint8_t*>(addr), value);
  }
};

class AvrDelay final : public drivers::Delay {
 public:
  void WaitMs(uint16_t ms) override {
    wdt_reset();
    const uint32_t deadline = SystemClock().NowUs() + 1000ul * ms;  // 32-bit: int is 16
    SleepUntil(deadline, [] { return false; });
  }
};

class AvrSystem final : public app::System {
 public:
  /// The reset command's ack is queued: send it, then let the watchdog reset the chip.
  void Reboot() override {
    SystemUart().Flush();
    cli();
    wdt_enable(WDTO_15MS);
    for (;;) {
    }
  }
};

class GpiorActivity final : public app::ActivityMarker {
 public:
  void Mark(uint8_t id) override { SetActivity(id); }
};

AvrEeprom g_eeprom;
AvrDelay g_delay;
AvrSystem g_system;
GpiorActivity g_activity;

}  // namespace

void BoardMain() {
  cli();
  SetActivity(app::activity::kOther);
  TIMSK0 = 0;  // under the Arduino core: its millis() tick would wake the CPU every 1.024 ms
  SystemClock().Init();
  SystemUart().Init();
  SystemTwi().Init();
  sei();

  // A fresh EEPROM's rate: the factory rig (four ADXL345 behind the TCA9548A) holds 340 Hz at
  // 7 % asleep, four BNO055 300 Hz at 14 % (`jointangle bench firmware`); 250 Hz leaves ~32 % and
  // ~28 % asleep (>= 20 %, issue 17).
  constexpr uint16_t kMegaFactoryRateHz = 250;
  // The TWI and UART interrupts that run while the loop waits: the loop's own busy time x 1.15 is
  // what the cycle-exact sleep count says (four ADXL345, full stream: the board's figure 330 Hz
  // without it, 290 Hz held at 20.5 % asleep in `bench firmware`'s loop).
  constexpr uint16_t kMegaBusyScalePermille = 1150;
  // Hal::bus_byte_ns stays 0 (the readings are not turned to the row's time, APP.md "Read
  // times"): at the factory ODR (1.6 x the rate) an ADXL345's own conversion clock, not the
  // read, sets its sample instant (its age is uniform over 1 / ODR = 2.5 ms at 250 Hz, against
  // 0.29 ms between reads: 11 bytes of 9 SCL at 400 kHz plus the TWI interrupt, ~26 us a
  // byte). Measured with 26 us on the virtual board (test_hil_accuracy, 250 Hz): 0.125 deg
  // steady RMS against 0.111 without, and ~3 k cycles a step.
  // Hal::scl_period_ns: TWBR 12 makes an SCL period 2.5 us, but the TWI holds SCL low while its
  // byte interrupt runs, ~26 us a byte of 9 SCL (above): 2889 ns a period. The bus then bounds
  // the rate at 760 Hz with the factory rig (435 SCL a loop), far above what the CPU holds
  // (~290 Hz): the Mega's rates stay the CPU's.
  constexpr uint16_t kMegaSclPeriodNs = (26000 + 4) / 9;
  Twi& twi = SystemTwi();
  // Placement new into static storage: a function-local static with a destructor would
  // register it with atexit(), which pulls in malloc (the app never frees or allocates).
  alignas(app::App) static uint8_t storage[sizeof(app::App)];
  app::App& app = *new (storage) app::App(
      app::Hal{twi, g_delay, SystemClock(), SystemUart(), g_eeprom, g_system,
               static_cast<uint8_t>(proto::Board::kMega2560), &twi, &g_activity, kMegaFactoryRateHz,
               kMegaBusyScalePermille, 0, kMegaSclPeriodNs});
  // APP.md "Watchdog": >= 1 s while Begin probes (BNO055 boot wait), >= 250 ms afterwards.
  wdt_enable(WDTO_1S);
  app.Begin();
  wdt_enable(WDTO_250MS);
  Usart0& uart = SystemUart();
  for (;;) {
    wdt_reset();
    const uint32_t idle_us = app.Poll();
    if (idle_us == 0) continue;
    // Asleep until the next period is due or a command byte arrives (other interrupts - TWI,
    // UART transmit, timer overflow - wake the CPU only to go back to sleep).
    SleepUntilWoken(SystemClock().NowUs() + idle_us, [&uart] { return uart.RxAvailable(); });
  }
}

}  // namespace avr
}  // namespace ja
