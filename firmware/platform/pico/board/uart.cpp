#include "platform/pico/board/uart.hpp"

#include <string.h>

#include "platform/pico/board/clock.hpp"

namespace ja {
namespace pico {

namespace {

using namespace hw;

constexpr uint8_t kRxSize = 128;  // power of two: the index wraps with a mask
constexpr uint32_t kFlushTimeoutUs = 20000;
// UARTIFLS: TX interrupt when the TX FIFO falls to <= 1/4 (8 bytes: 80 us of line at 1 Mbaud
// for the interrupt to come), RX interrupt at >= 1/4 (8 of 32 bytes).
constexpr uint32_t kIfls = (1u << 3) | 1u;

// Transmit ring: 256 bytes, one-byte indices that wrap by themselves; 255 usable (head == tail
// is empty). The app writes head (TxWrite), the FIFO feeder (interrupt or TxWrite's priming,
// each with interrupts off) writes tail.
uint8_t g_tx_buf[256];
volatile uint8_t g_tx_head = 0;
volatile uint8_t g_tx_tail = 0;
uint8_t g_rx[kRxSize];
volatile uint16_t g_rx_overflows = 0;
uint32_t g_imsc = 0;  // UARTIMSC as last written (changed with interrupts off only)
Uart0 g_uart;

inline void SetMask(uint32_t imsc) {
  if (imsc != g_imsc) {
    g_imsc = imsc;
    Reg(kUartImsc) = imsc;
  }
}

/// Moves ring bytes into the TX FIFO until it is full or the ring is empty; the TX interrupt is
/// wanted only while bytes remain (then the FIFO was filled, and its draining to the trigger
/// level raises it). Interrupts off (or in the interrupt).
void FeedTx() {
  uint8_t t = g_tx_tail;
  const uint8_t h = g_tx_head;
  while (t != h && !(Reg(kUartFr) & kUartFrTxff)) {
    Reg(kUartDr) = g_tx_buf[t];
    t = static_cast<uint8_t>(t + 1);
  }
  g_tx_tail = t;
  SetMask(t != h ? (g_imsc | kUartIntTx) : (g_imsc & ~kUartIntTx));
}

void DrainRx() {
  while (!(Reg(kUartFr) & kUartFrRxfe)) {
    const uint8_t b = static_cast<uint8_t>(Reg(kUartDr));  // error flags in bits 11:8 dropped
    const uint8_t h = detail::g_rx_head;
    const uint8_t next = static_cast<uint8_t>((h + 1) & (kRxSize - 1));
    if (next == detail::g_rx_tail) {
      g_rx_overflows = static_cast<uint16_t>(g_rx_overflows + 1);
      continue;
    }
    g_rx[h] = b;
    detail::g_rx_head = next;
  }
}

}  // namespace

namespace detail {
volatile uint8_t g_rx_head = 0;  // written by the interrupt only
volatile uint8_t g_rx_tail = 0;  // written by the main loop only
}  // namespace detail

Uart0& SystemUart() { return g_uart; }

void Uart0::Init() {
  Reg(kUartCr) = 0;
  Reg(kUartIbrd) = kIbrd;
  Reg(kUartFbrd) = kFbrd;
  Reg(kUartLcrH) = kUartLcrHWlen8 | kUartLcrHFen;  // latches IBRD/FBRD; 8N1, FIFOs on
  Reg(kUartIfls) = kIfls;
  Reg(kUartIcr) = kUartIntAll;
  g_imsc = kUartIntRx | kUartIntRt;
  Reg(kUartImsc) = g_imsc;
  Reg(kUartCr) = kUartCrUarten | kUartCrTxe | kUartCrRxe;
  EnableIrq(kIrqUart0);
}

uint16_t Uart0::TxFree() {
  return static_cast<uint16_t>(255u - static_cast<uint8_t>(g_tx_head - g_tx_tail));
}

void Uart0::TxWrite(const uint8_t* data, uint16_t n) {
  if (n > TxFree()) return;  // the app never writes more
  const uint8_t h = g_tx_head;
  const uint16_t first = static_cast<uint16_t>(256u - h);
  if (n <= first) {
    memcpy(g_tx_buf + h, data, n);
  } else {
    memcpy(g_tx_buf + h, data, first);
    memcpy(g_tx_buf, data + first, n - first);
  }
  __asm volatile("" ::: "memory");  // the bytes are stored before head publishes them
  g_tx_head = static_cast<uint8_t>(h + n);
  const uint32_t primask = SaveAndDisableInterrupts();
  FeedTx();
  RestoreInterrupts(primask);
}

int16_t Uart0::RxRead() {
  const uint8_t t = detail::g_rx_tail;
  if (t == detail::g_rx_head) return -1;
  const uint8_t b = g_rx[t];
  detail::g_rx_tail = static_cast<uint8_t>((t + 1) & (kRxSize - 1));
  return b;
}

void Uart0::Flush() {
  const uint32_t start = SystemClock().NowUs();
  while (SystemClock().NowUs() - start < kFlushTimeoutUs) {
    const uint32_t primask = SaveAndDisableInterrupts();
    FeedTx();
    const bool queued = g_tx_head != g_tx_tail;
    RestoreInterrupts(primask);
    if (!queued && !(Reg(kUartFr) & kUartFrBusy)) return;
  }
}

uint16_t Uart0::rx_overflows() const { return g_rx_overflows; }

}  // namespace pico
}  // namespace ja

extern "C" void isr_uart0() {
  using namespace ja::pico::hw;
  const uint32_t mis = Reg(kUartMis);
  if (mis & (kUartIntRx | kUartIntRt)) ja::pico::DrainRx();
  if (mis & kUartIntErrors) Reg(kUartIcr) = kUartIntErrors;
  if (mis & kUartIntTx) ja::pico::FeedTx();
}
