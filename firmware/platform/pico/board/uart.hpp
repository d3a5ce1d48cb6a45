// UART0 (an ARM PL011, RP2040 datasheet 4.2) on GP0/GP1 as the app's serial port: 1 000 000 baud
// 8N1, FIFOs on (32 bytes each way). Transmit: the app's whole frames go into a 255-byte ring
// (as the Mega's); TxWrite primes the TX FIFO itself and the UART0 interrupt refills it each
// time it drains to a quarter (the PL011's TX interrupt marks the FIFO falling to its trigger
// level, so a driver must fill the FIFO first and never waits for an interrupt on an idle
// transmitter). Receive: the RX interrupt (FIFO a quarter full) and the receive timeout (32 bit
// times without a byte) drain the FIFO into a 128-byte ring; bytes arriving with it full are
// dropped and counted (the app's decoder then sees a broken frame and counts it).
#pragma once

#include <stdint.h>

#include "app/hal.hpp"
#include "platform/pico/board/rp2040.hpp"

namespace ja {
namespace pico {

namespace detail {
extern volatile uint8_t g_rx_head;
extern volatile uint8_t g_rx_tail;
}  // namespace detail

class Uart0 final : public app::SerialPort {
 public:
  // 1000 Hz with four sensors streams 70-byte frames plus status: 700 kbaud of payload; a
  // Pico's UART bridge (Raspberry Pi Debug Probe, FT232R, CP2102N, CH340) carries 1 Mbaud.
  static constexpr uint32_t kBaud = 1000000;
  // The PL011 divisor, clk_peri / (16 baud), in 1/64ths (IBRD.FBRD), rounded to nearest:
  // 125 MHz / 16 MHz = 7.8125 = 7 + 52/64, exact.
  static constexpr uint32_t kDivisor64 = (4 * hw::kClkPeriHz + kBaud / 2) / kBaud;
  static constexpr uint32_t kIbrd = kDivisor64 >> 6;
  static constexpr uint32_t kFbrd = kDivisor64 & 63;

  /// Divisor, 8N1, FIFOs, interrupts. Call once after InitChip.
  void Init();
  uint16_t TxFree() override;
  void TxWrite(const uint8_t* data, uint16_t n) override;
  int16_t RxRead() override;
  /// Inline: the sleep loop tests it after every interrupt.
  bool RxAvailable() const { return detail::g_rx_tail != detail::g_rx_head; }
  /// Waits until every queued byte has left the transmitter, or 20 ms (feeds the FIFO itself,
  /// so it works with interrupts off).
  void Flush();
  uint16_t rx_overflows() const;
};

static_assert(Uart0::kIbrd >= 1 && Uart0::kIbrd <= 65534, "PL011 IBRD range");
// Within 1 % of the requested rate (receivers tolerate ~2 %).
static_assert(4 * hw::kClkPeriHz / Uart0::kDivisor64 <= Uart0::kBaud + Uart0::kBaud / 100 &&
                  4 * hw::kClkPeriHz / Uart0::kDivisor64 >= Uart0::kBaud - Uart0::kBaud / 100,
              "baud rate error above 1 %");

Uart0& SystemUart();

}  // namespace pico
}  // namespace ja
