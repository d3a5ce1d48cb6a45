// Links the application for the ATmega2560 over do-nothing hardware, so avr-size can report its
// flash and RAM (ctest firmware.app_builds_for_avr). The real board is issue 6's.
#include "app/app.hpp"
#include "app/tx_ring.hpp"

namespace {

class StubBus final : public ja::drivers::I2cBus {
 public:
  ja::drivers::I2cStatus Read(uint8_t, uint8_t, uint8_t*, uint8_t) override {
    return ja::drivers::I2cStatus::kNack;
  }
  ja::drivers::I2cStatus Write(uint8_t, uint8_t, const uint8_t*, uint8_t) override {
    return ja::drivers::I2cStatus::kNack;
  }
};
class StubDelay final : public ja::drivers::Delay {
 public:
  void WaitMs(uint16_t) override {}
};
class StubClock final : public ja::app::Clock {
 public:
  uint32_t NowUs() override { return now += 100; }
  volatile uint32_t now = 0;
};
class StubSerial final : public ja::app::SerialPort {
 public:
  uint16_t TxFree() override { return ring.Free(); }
  void TxWrite(const uint8_t* d, uint16_t n) override {
    ring.Write(d, n);
    uint8_t b;
    while (ring.Pop(&b)) sink = b;  // stands in for the UDRE interrupt
  }
  ja::app::TxRing ring;
  int16_t RxRead() override { return -1; }
  volatile uint8_t sink = 0;
};
class StubEeprom final : public ja::app::Eeprom {
 public:
  uint16_t Size() override { return 4096; }
  uint8_t Read(uint16_t) override { return 0xFF; }
  void Write(uint16_t, uint8_t v) override { sink = v; }
  volatile uint8_t sink = 0;
};
class StubSystem final : public ja::app::System {
 public:
  void Reboot() override {}
};

StubBus bus;
StubDelay delay;
StubClock clock;
StubSerial serial;
StubEeprom eeprom;
StubSystem sys;

}  // namespace

int main() {
  static ja::app::App app(ja::app::Hal{bus, delay, clock, serial, eeprom, sys, 1});
  app.Begin();
  for (;;) app.Poll();
}
