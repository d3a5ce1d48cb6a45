#include "platform/avr/board/uart.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <string.h>
#include <util/atomic.h>
#include <util/delay.h>

#include "platform/avr/board/activity.hpp"
#include "platform/avr/board/clock.hpp"

namespace ja {
namespace avr {

namespace {

constexpr uint8_t kRxSize = 128;  // power of two: the index wraps with a mask
// Transmit ring: 256 bytes, one-byte indices that wrap by themselves; 255 usable (head == tail
// is empty). The app writes head, the UDRE interrupt (assembly below) writes tail.
// 256-aligned: the UDRE interrupt addresses it as (hi8(buf), tail) with no addition.
uint8_t g_tx_buf[256] __attribute__((aligned(256)));
volatile uint8_t g_tx_head = 0;
volatile uint8_t g_tx_tail = 0;
uint8_t g_rx[kRxSize];
volatile uint16_t g_rx_overflows = 0;
Usart0 g_uart;

}  // namespace

namespace detail {
volatile uint8_t g_rx_head = 0;  // written by the RX interrupt only
volatile uint8_t g_rx_tail = 0;  // written by the main loop only
}  // namespace detail

Usart0& SystemUart() { return g_uart; }

void Usart0::Init() {
  // simavr computes the baud rate when UBRR0L is written and reads U2X0 then (docs/sensors.md §D2):
  // mode bits first, the divider last. Real silicon does not care about the order.
  UCSR0A = _BV(U2X0);
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
  UBRR0H = 0;
  UBRR0L = kUbrr;
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

uint16_t Usart0::TxFree() {
  return static_cast<uint16_t>(255u - static_cast<uint8_t>(g_tx_head - g_tx_tail));
}

void Usart0::TxWrite(const uint8_t* data, uint16_t n) {
  if (n > TxFree()) return;  // the app never writes more
  // At most two contiguous pieces (up to the end of the ring, then from its start), each one
  // avr-libc memcpy (~8 cycles a byte; the indexed byte loop took ~11-14).
  const uint8_t h = g_tx_head;
  const uint16_t first = static_cast<uint16_t>(256u - h);
  if (n <= first) {
    memcpy(g_tx_buf + h, data, n);
  } else {
    memcpy(g_tx_buf + h, data, first);
    memcpy(g_tx_buf, data + first, n - first);
  }
  g_tx_head = static_cast<uint8_t>(h + n);  // publish after the bytes are stored
  // UCSR0B is not bit-addressable: read-modify-write with interrupts off (the UDRE interrupt
  // clears UDRIE0 when the ring runs empty).
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= _BV(UDRIE0); }
}

bool Usart0::TxFrame(const proto::FrameHeader& header, uint8_t* frame, uint16_t payload_len,
                     uint16_t n) {
  if (n > TxFree()) return false;  // the app checked; then TxWrite ignores it as well
  const uint8_t h = g_tx_head;
  // Written past head only (the UDRE interrupt reads up to head): then published.
  if (proto::finish_frame_to_ring(header, payload_len, frame, g_tx_buf, h) != n) return false;
  g_tx_head = static_cast<uint8_t>(h + n);
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= _BV(UDRIE0); }
  return true;
}

int16_t Usart0::RxRead() {
  const uint8_t t = detail::g_rx_tail;
  if (t == detail::g_rx_head) return -1;
  const uint8_t b = g_rx[t];
  detail::g_rx_tail = static_cast<uint8_t>((t + 1) & (kRxSize - 1));
  return b;
}

void Usart0::Flush() {
  // 255 bytes at 500 kbaud take 5.1 ms; give up after ~10 ms (interrupts must be on). The
  // last byte leaves UDR0 and the shift register within two byte times (40 us) of the ring
  // running empty.
  for (uint16_t i = 0; i < 1000 && (g_tx_head != g_tx_tail || (UCSR0B & _BV(UDRIE0))); ++i) {
    _delay_us(10);
  }
  _delay_us(50);
}

uint16_t Usart0::rx_overflows() const {
  uint16_t v;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { v = g_rx_overflows; }
  return v;
}

}  // namespace avr
}  // namespace ja

// One byte from the ring into UDR0, or UDRIE0 off when the ring is empty. In assembly: it runs
// once per byte sent (~35 000 times a second while streaming at 500 Hz). The send path changes
// no flag (cpse, ld Z+, no add or compare), so SREG is saved only on the rare empty path; the
// ring is 256-aligned, so Z = (hi8(buf), tail) and `ld Z+` leaves the next tail in r30 (its
// carry into r31 is dropped: the index wraps at 256 with the ring). ~47 cycles a byte with the
// interrupt response (the compiler's version ~80, the former assembly ~61).
// Activity id 2 (activity.hpp) in GPIOR1 while it runs, the interrupted id restored.
ISR(USART0_UDRE_vect, ISR_NAKED) {
  asm volatile(
      "push r30                      \n\t"
      "push r31                      \n\t"
      "push r24                      \n\t"
      "push r25                      \n\t"
      "in   r25, %[gpior]            \n\t"  // interrupted activity
      "ldi  r24, %[id]               \n\t"
      "out  %[gpior], r24            \n\t"
      "lds  r30, %[tail]             \n\t"
      "lds  r24, %[head]             \n\t"
      "cpse r30, r24                 \n\t"
      "rjmp 1f                       \n\t"
      // empty: no more UDRE interrupts (andi changes flags: SREG saved here only)
      "in   r24, __SREG__            \n\t"
      "push r24                      \n\t"
      "lds  r24, %[ucsrb]            \n\t"
      "andi r24, %[no_udrie]         \n\t"
      "sts  %[ucsrb], r24            \n\t"
      "pop  r24                      \n\t"
      "out  __SREG__, r24            \n\t"
      "rjmp 2f                       \n\t"
      "1:                            \n\t"
      "ldi  r31, hi8(%[buf])         \n\t"  // Z = buf + tail
      "ld   r24, Z+                  \n\t"
      "sts  %[udr], r24              \n\t"
      "sts  %[tail], r30             \n\t"  // tail + 1 (mod 256)
      "2:                            \n\t"
      "out  %[gpior], r25            \n\t"
      "pop  r25                      \n\t"
      "pop  r24                      \n\t"
      "pop  r31                      \n\t"
      "pop  r30                      \n\t"
      "reti                          \n\t" ::[gpior] "I"(_SFR_IO_ADDR(GPIOR1)),
      [id] "M"(ja::app::activity::kUartIsr), [tail] "i"(&ja::avr::g_tx_tail),
      [head] "i"(&ja::avr::g_tx_head), [buf] "i"(ja::avr::g_tx_buf), [udr] "n"(_SFR_MEM_ADDR(UDR0)),
      [ucsrb] "n"(_SFR_MEM_ADDR(UCSR0B)), [no_udrie] "n"(0xFF & ~_BV(UDRIE0)));
}

ISR(USART0_RX_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kUartIsr);
  ja::avr::WakeMainLoop();  // a command byte ends the main loop's sleep
  const uint8_t b = UDR0;
  const uint8_t h = ja::avr::detail::g_rx_head;
  const uint8_t next = static_cast<uint8_t>((h + 1) & (ja::avr::kRxSize - 1));
  if (next == ja::avr::detail::g_rx_tail) {
    ja::avr::g_rx_overflows = ja::avr::g_rx_overflows + 1;
    return;
  }
  ja::avr::g_rx[h] = b;
  ja::avr::detail::g_rx_head = next;
}
