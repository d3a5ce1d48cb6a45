#include "platform/pico/board/board.hpp"

#include <new>

#include "app/app.hpp"
#include "platform/pico/board/chip.hpp"
#include "platform/pico/board/clock.hpp"
#include "platform/pico/board/flash_store.hpp"
#include "platform/pico/board/i2c.hpp"
#include "platform/pico/board/uart.hpp"
#include "protocol/messages.hpp"

// A pure virtual function called (never, the app builds whole objects): stop here. Defined so
// the link does not pull in libstdc++'s, which brings std::terminate and its unwinder.
extern "C" void __cxa_pure_virtual() {
  for (;;) {
    __asm volatile("" ::: "memory");
  }
}

namespace ja {
namespace pico {

namespace {

class PicoDelay final : public drivers::Delay {
 public:
  void WaitMs(uint16_t ms) override {
    WatchdogKick();
    SleepUntil(SystemClock().NowUs() + 1000u * ms, [] { return false; });
  }
};

class PicoSystem final : public app::System {
 public:
  /// The reset command's ack is queued: send it, then let the watchdog reset the chip.
  void Reboot() override {
    SystemUart().Flush();
    WatchdogReboot();
  }
};

FlashEeprom g_eeprom;
PicoDelay g_delay;
PicoSystem g_system;

}  // namespace

void BoardMain() {
  InitChip();
  SystemClock().Init();
  SystemUart().Init();
  SystemI2c().Init();
  g_eeprom.Init();

  // A fresh flash's rate. Four ADXL345 a channel each behind the TCA9548A take 435 SCL a loop,
  // 1.09 ms at 400 kHz: the bus, not the CPU, sets the limit (the app's bound: 880 Hz; 800 Hz
  // holds every frame at 87 % bus with the CPU ~80 % asleep; firmware/platform/pico/README.md
  // "Rates"). Two a channel hold 1000 Hz.
  constexpr uint16_t kPicoFactoryRateHz = 800;
  // Hal::busy_scale_permille and bus_byte_ns stay 0 (x 1.0; reads not turned to the row's time)
  // until measured on this board, as the Mega decides (platform/avr/board/board.cpp).
  // Hal::scl_period_ns = I2C0's programmed period (2504 ns): the app bounds its sustainable rate
  // by the bus (880 Hz with the factory rig, 1000 Hz with two ADXL345 a channel).
  I2c0& i2c = SystemI2c();
  // Placement new into static storage: a function-local static with a destructor would
  // register it with atexit() (the app never frees or allocates).
  alignas(app::App) static uint8_t storage[sizeof(app::App)];
  app::App& app = *new (storage) app::App(
      app::Hal{i2c, g_delay, SystemClock(), SystemUart(), g_eeprom, g_system,
               static_cast<uint8_t>(proto::Board::kPico), &i2c, nullptr, kPicoFactoryRateHz, 0, 0,
               static_cast<uint16_t>(i2c_timing::kPeriodNs)});
  // APP.md "Watchdog": >= 1 s while Begin probes (BNO055 boot wait), >= 250 ms afterwards.
  WatchdogStart(1000);
  app.Begin();
  WatchdogStart(250);
  Uart0& uart = SystemUart();
  for (;;) {
    WatchdogKick();
    const uint32_t idle_us = app.Poll();
    if (idle_us == 0) continue;
    // Asleep until the next period is due or a command byte arrives (other interrupts - I2C,
    // UART transmit - wake the CPU only to go back to sleep).
    SleepUntil(SystemClock().NowUs() + idle_us, [&uart] { return uart.RxAvailable(); });
  }
}

}  // namespace pico
}  // namespace ja
