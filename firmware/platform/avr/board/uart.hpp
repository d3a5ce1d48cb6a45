// USART0 (the Mega's USB bridge): 500 000 baud 8N1, U2X0 = 1, UBRR0 = 3 (exact at 16 MHz:
// 16e6 / (8 (3 + 1)) = 500 000; README.md next to this file: why this rate). Transmit: the app's
// whole frames go into a 255-byte ring that the UDRE interrupt (assembly) drains; the app
// asks TxFree() first and drops (counts) a frame that does not fit. Receive: the RX interrupt
// fills a 128-byte ring; bytes arriving with it full are dropped and counted (the app's decoder
// then sees a broken frame and counts it).
#pragma once

#include <stdint.h>

#include "app/hal.hpp"

namespace ja {
namespace avr {

namespace detail {
extern volatile uint8_t g_rx_head;
extern volatile uint8_t g_rx_tail;
}  // namespace detail

class Usart0 final : public app::SerialPort {
 public:
  static constexpr uint32_t kBaud = 500000;
  static constexpr uint8_t kUbrr = 3;  // with U2X0

  /// Call once with interrupts off.
  void Init();
  uint16_t TxFree() override;
  void TxWrite(const uint8_t* data, uint16_t n) override;
  /// Encodes the frame straight into the ring (proto::finish_frame_to_ring): no copy.
  bool TxFrame(const proto::FrameHeader& header, uint8_t* frame, uint16_t payload_len,
               uint16_t n) override;
  int16_t RxRead() override;
  /// Inline: the sleep loop tests it after every interrupt.
  bool RxAvailable() const { return detail::g_rx_tail != detail::g_rx_head; }
  /// Waits (interrupts on) until every queued byte has left the shift register, or ~10 ms.
  void Flush();
  uint16_t rx_overflows() const;
};

Usart0& SystemUart();

}  // namespace avr
}  // namespace ja
