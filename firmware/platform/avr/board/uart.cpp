#include "platform/avr/board/uart.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>
#include <util/delay.h>

#include "platform/avr/board/activity.hpp"

namespace ja {
namespace avr {

namespace {

constexpr uint8_t kRxSize = 128;  // power of two: the index wraps with a mask
app::TxRing g_tx;
uint8_t g_rx[kRxSize];
volatile uint8_t g_rx_head = 0;  // written by the RX interrupt only
volatile uint8_t g_rx_tail = 0;  // written by the main loop only
volatile uint16_t g_rx_overflows = 0;
Usart0 g_uart;

}  // namespace

Usart0& SystemUart() { return g_uart; }

void Usart0::Init() {
  // simavr computes the baud rate when UBRR0L is written and reads U2X0 then (SENSORS.md D2):
  // mode bits first, the divider last. Real silicon does not care about the order.
  UCSR0A = _BV(U2X0);
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
  UBRR0H = 0;
  UBRR0L = kUbrr;
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

uint16_t Usart0::TxFree() { return g_tx.Free(); }

void Usart0::TxWrite(const uint8_t* data, uint16_t n) {
  g_tx.Write(data, n);
  // UCSR0B is not bit-addressable: read-modify-write with interrupts off (the UDRE interrupt
  // clears UDRIE0 when the ring runs empty).
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= _BV(UDRIE0); }
}

int16_t Usart0::RxRead() {
  const uint8_t t = g_rx_tail;
  if (t == g_rx_head) return -1;
  const uint8_t b = g_rx[t];
  g_rx_tail = static_cast<uint8_t>((t + 1) & (kRxSize - 1));
  return b;
}

bool Usart0::RxAvailable() const { return g_rx_tail != g_rx_head; }

void Usart0::Flush() {
  // 255 bytes at 500 kbaud take 5.1 ms; give up after ~10 ms (interrupts must be on).
  for (uint16_t i = 0; i < 1000; ++i) {
    const bool empty = g_tx.Used() == 0 && !(UCSR0B & _BV(UDRIE0));
    if (empty && (UCSR0A & _BV(TXC0))) return;
    _delay_us(10);
  }
}

uint16_t Usart0::rx_overflows() const {
  uint16_t v;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { v = g_rx_overflows; }
  return v;
}

}  // namespace avr
}  // namespace ja

ISR(USART0_UDRE_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kUartIsr);
  uint8_t b;
  if (ja::avr::g_tx.Pop(&b)) {
    UCSR0A = static_cast<uint8_t>((UCSR0A & _BV(U2X0)) | _BV(TXC0));  // clear TXC: Flush waits
    UDR0 = b;
  } else {
    UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));
  }
}

ISR(USART0_RX_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kUartIsr);
  const uint8_t b = UDR0;
  const uint8_t h = ja::avr::g_rx_head;
  const uint8_t next = static_cast<uint8_t>((h + 1) & (ja::avr::kRxSize - 1));
  if (next == ja::avr::g_rx_tail) {
    ja::avr::g_rx_overflows = ja::avr::g_rx_overflows + 1;
    return;
  }
  ja::avr::g_rx[h] = b;
  ja::avr::g_rx_head = next;
}
