// I2C0 (a Synopsys DW_apb_i2c, RP2040 datasheet 4.3) on GP4/GP5: master, 7-bit addresses, fast
// mode 400 kHz, driven by its interrupt. One engine serves both views the app needs
// (app/hal.hpp), as the Mega's TWI does:
// - I2cBatch: the steady-state sample reads; Start() returns at once and the I2C0 interrupt
//   walks the transfer list while the CPU filters;
// - drivers::I2cBus: probing and configuration; each call waits (asleep) for the batch in
//   flight, then runs its one transaction on the same engine and waits (asleep) for it.
// A transfer is commands in the TX FIFO: the register byte, then its reads (the first with
// RESTART: repeated START, SLA+R) or a write's data bytes, the last one with STOP. The target
// address (IC_TAR) changes only with the block disabled, so each transfer starts with
// IC_ENABLE 0, IC_TAR, IC_ENABLE 1. A short transfer (an ADXL345 read: register + 6 reads)
// fits the 16-entry FIFO whole and costs one interrupt, at its STOP; longer ones are fed on
// TX_EMPTY and drained on RX_FULL, never more reads in flight than the RX FIFO holds.
// Per transfer: an address NACK (ABRT_7B_ADDR_NOACK) or a data NACK (ABRT_TXDATA_NOACK) is
// kNack, any other abort (arbitration lost) kBusError, and a transfer that does not finish in
// time (stuck bus, endless clock stretching) is kTimeout: the block is reset and reconfigured.
#pragma once

#include <stdint.h>

#include "app/hal.hpp"
#include "drivers/i2c_bus.hpp"
#include "platform/pico/board/rp2040.hpp"

namespace ja {
namespace pico {

// SCL at 400 kHz from ic_clk = clk_sys = 125 MHz (datasheet 4.3.14): the SCL low time is
// IC_FS_SCL_LCNT + 1 clocks, the high time IC_FS_SCL_HCNT + IC_FS_SPKLEN + 7 (the bus's rise
// time comes on top). Fast mode asks tLOW >= 1.3 us, tHIGH >= 0.6 us, spikes up to 50 ns
// suppressed; 313 clocks a period (399.4 kHz), 60 % of it low as Raspberry Pi's SDK splits it.
namespace i2c_timing {
constexpr uint32_t kSclHz = 400000;
constexpr uint32_t kPeriodClocks = (hw::kClkSysHz + kSclHz / 2) / kSclHz;  // 313
constexpr uint32_t kLowClocks = kPeriodClocks * 3 / 5;                     // 187: 1.50 us
constexpr uint32_t kHighClocks = kPeriodClocks - kLowClocks;               // 126: 1.01 us
constexpr uint32_t kSpklen = 50 * (hw::kClkSysHz / 1000000) / 1000;        // 6 clocks: 48 ns
constexpr uint32_t kLcnt = kLowClocks - 1;
constexpr uint32_t kHcnt = kHighClocks - kSpklen - 7;
// The period in ns (Hal::scl_period_ns: the bus's bound on the rate): 2504.
constexpr uint32_t kPeriodNs =
    static_cast<uint32_t>((kPeriodClocks * 1000000000ull + hw::kClkSysHz / 2) / hw::kClkSysHz);
static_assert(kPeriodNs == 2504, "313 clocks at 125 MHz");
// SDA held 300 ns after SCL falls (the SDK's figure, past SCL's own fall time).
constexpr uint32_t kSdaTxHold = (3 * hw::kClkSysHz + 9999999) / 10000000;  // 38 clocks
static_assert(kLowClocks * 1000000000ull >= 1300ull * hw::kClkSysHz, "tLOW >= 1.3 us");
static_assert(kHighClocks * 1000000000ull >= 600ull * hw::kClkSysHz, "tHIGH >= 0.6 us");
static_assert(kLcnt >= 8 && kHcnt >= 6 && kSpklen >= 1, "the block's minimum counts");
static_assert(kSdaTxHold < kLcnt - 2, "SDA hold within the low period");
}  // namespace i2c_timing

class I2c0 final : public drivers::I2cBus, public app::I2cBatch {
 public:
  static constexpr uint32_t kTransferTimeoutUs = 5000;
  static constexpr uint32_t kBatchTimeoutUs = 20000;

  /// Timing, master mode, interrupt. Call once after InitChip.
  void Init();

  drivers::I2cStatus Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) override;
  drivers::I2cStatus Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) override;

  void Start(app::I2cTransfer* t, uint8_t count) override;
  void Wait() override;

  bool busy() const;
  uint16_t timeouts() const { return timeouts_; }

 private:
  /// Waits (asleep) until the engine is idle; on timeout resets the block. True if it finished.
  bool WaitIdle(uint32_t timeout_us);
  /// Starts the list on the idle engine (a batch, or Read/Write's one transfer with the write
  /// data set).
  void Run(app::I2cTransfer* t, uint8_t count);
  uint16_t timeouts_ = 0;
};

I2c0& SystemI2c();

}  // namespace pico
}  // namespace ja
