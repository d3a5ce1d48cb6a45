#include "platform/avr/board/twi.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <stddef.h>

#include "platform/avr/board/activity.hpp"
#include "platform/avr/board/clock.hpp"

namespace ja {
namespace avr {

namespace {

using drivers::I2cStatus;

// TWSR status codes (ATmega2560 datasheet, TWI master transmitter/receiver tables).
constexpr uint8_t kStart = 0x08, kRepStart = 0x10, kSlaWAck = 0x18, kSlaWNack = 0x20,
                  kDataAck = 0x28, kDataNack = 0x30, kSlaRAck = 0x40, kSlaRNack = 0x48,
                  kRxAck = 0x50, kRxNack = 0x58;

enum class Phase : uint8_t { kIdle, kStart, kSlaW, kWrite, kRepStart, kSlaR, kRead };
// The assembly in TWI_vect uses these numbers.
static_assert(static_cast<uint8_t>(Phase::kStart) == 1 && static_cast<uint8_t>(Phase::kSlaW) == 2 &&
                  static_cast<uint8_t>(Phase::kWrite) == 3 &&
                  static_cast<uint8_t>(Phase::kRepStart) == 4 &&
                  static_cast<uint8_t>(Phase::kSlaR) == 5 &&
                  static_cast<uint8_t>(Phase::kRead) == 6,
              "Phase numbering");

// The layout TWI_vect's assembly assumes (7 g_index computed as 8 g_index - g_index).
static_assert(sizeof(app::I2cTransfer) == 7 && offsetof(app::I2cTransfer, addr7) == 0 &&
                  offsetof(app::I2cTransfer, reg) == 1 && offsetof(app::I2cTransfer, n) == 2,
              "I2cTransfer layout");
static_assert(static_cast<uint8_t>(I2cStatus::kOk) == 0 && static_cast<uint8_t>(Phase::kIdle) == 0,
              "zero values");

// Engine state: written by the interrupt while busy, by the main context only while idle.
app::I2cTransfer* g_ops = nullptr;
uint8_t g_count = 0;
uint8_t g_index = 0;
uint8_t g_pos = 0;  // bytes written after the register / bytes read
// The receive fast path (TWI_vect in assembly below) works on these two: where the next byte
// goes and how many bytes are still to come.
uint8_t* volatile g_rptr = nullptr;
volatile uint8_t g_rleft = 0;
const uint8_t* g_wbuf = nullptr;  // blocking Write: the data after the register
uint8_t g_wn = 0;                 //
volatile Phase g_phase = Phase::kIdle;
volatile uint8_t g_sla = 0;  // the SLA+R/W byte to send after the (repeated) START
volatile uint8_t g_reg = 0;  // the register byte sent after SLA+W
volatile bool g_busy = false;
app::I2cTransfer g_single;  // the blocking path's one transfer (n = 0: a write)
Twi g_twi;

constexpr uint8_t kRun = _BV(TWINT) | _BV(TWEN) | _BV(TWIE);

inline void Go(uint8_t extra) { TWCR = static_cast<uint8_t>(kRun | extra); }

/// Starts the next transfer whose dependency succeeded (the others get kBusError); idle at
/// the end of the list.
inline void StartNext() {
  while (g_index < g_count) {
    app::I2cTransfer& t = g_ops[g_index];
    if (t.after != app::I2cTransfer::kNoDependency && g_ops[t.after].status != I2cStatus::kOk) {
      t.status = I2cStatus::kBusError;
      ++g_index;
      continue;
    }
    g_pos = 0;
    g_sla = static_cast<uint8_t>(t.addr7 << 1);  // SLA+W
    g_reg = t.reg;
    g_rptr = t.buf;
    g_rleft = t.n;  // 0: a write (its data bytes go through the C code)
    g_phase = Phase::kStart;
    Go(_BV(TWSTA));
    return;
  }
  g_phase = Phase::kIdle;
  g_busy = false;
}

/// Ends the current transfer with `st` (STOP, or just release the bus after a lost
/// arbitration) and starts the next one.
inline void Finish(I2cStatus st, bool stop) {
  g_ops[g_index].status = st;
  ++g_index;
  if (stop) {
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    // The STOP takes about half an SCL period; a START requested before it is done would be
    // lost. Bounded: 255 polls are ~80 us.
    for (uint8_t i = 0; i < 255 && (TWCR & _BV(TWSTO)); ++i) {
    }
  } else {
    TWCR = _BV(TWINT) | _BV(TWEN);
  }
  StartNext();
}

/// One TWI interrupt: the phase says what was just sent; TWSR says how it went.
inline void OnTwi() {
  const uint8_t st = TWSR & 0xF8;
  app::I2cTransfer& t = g_ops[g_index];
  // 0x00: illegal START/STOP on the bus. The datasheet's recovery is TWSTO + TWINT (no STOP
  // goes out; the TWI is released), which is what Finish(.., true) writes.
  if (st == 0x00 && g_phase != Phase::kIdle) return Finish(I2cStatus::kBusError, true);
  switch (g_phase) {
    case Phase::kStart:
      if (st != kStart && st != kRepStart) return Finish(I2cStatus::kBusError, false);
      TWDR = static_cast<uint8_t>(t.addr7 << 1);  // SLA+W
      g_phase = Phase::kSlaW;
      return Go(0);
    case Phase::kSlaW:
      // 0x28/0x30 here: simavr 1.6 reports SLA+W like a data byte (docs/sensors.md §D2).
      if (st == kSlaWNack || st == kDataNack) return Finish(I2cStatus::kNack, true);
      if (st != kSlaWAck && st != kDataAck) return Finish(I2cStatus::kBusError, false);
      TWDR = t.reg;
      g_phase = Phase::kWrite;
      return Go(0);
    case Phase::kWrite:
      if (st == kDataNack) return Finish(I2cStatus::kNack, true);
      if (st != kDataAck) return Finish(I2cStatus::kBusError, false);
      if (t.n == 0) {  // a write: the data after the register, then STOP
        if (g_pos < g_wn) {
          TWDR = g_wbuf[g_pos++];
          return Go(0);
        }
        return Finish(I2cStatus::kOk, true);
      }
      g_sla = static_cast<uint8_t>((t.addr7 << 1) | 1);  // SLA+R
      g_phase = Phase::kRepStart;
      return Go(_BV(TWSTA));
    case Phase::kRepStart:
      if (st != kRepStart && st != kStart) return Finish(I2cStatus::kBusError, false);
      TWDR = static_cast<uint8_t>((t.addr7 << 1) | 1);  // SLA+R
      g_phase = Phase::kSlaR;
      return Go(0);
    case Phase::kSlaR:
      if (st == kSlaRNack) return Finish(I2cStatus::kNack, true);
      if (st != kSlaRAck) return Finish(I2cStatus::kBusError, false);
      g_phase = Phase::kRead;
      g_rptr = t.buf;
      g_rleft = t.n;
      return Go(t.n > 1 ? _BV(TWEA) : 0);  // NACK the last byte
    case Phase::kRead: {
      // 0x50 (a byte ACKed, more to come) is normally taken by the assembly fast path; the
      // last byte (0x58) and errors come here.
      if (st != kRxAck && st != kRxNack) return Finish(I2cStatus::kBusError, false);
      uint8_t* p = g_rptr;
      *p++ = TWDR;
      g_rptr = p;
      const uint8_t left = static_cast<uint8_t>(g_rleft - 1);
      g_rleft = left;
      if (st == kRxNack || left == 0) return Finish(I2cStatus::kOk, true);
      return Go(left > 1 ? _BV(TWEA) : 0);
    }
    case Phase::kIdle:
      TWCR = _BV(TWEN);  // spurious: disable the interrupt
      return;
  }
}

}  // namespace

Twi& SystemTwi() { return g_twi; }

void Twi::Init() {
  PORTD |= _BV(PD0) | _BV(PD1);  // SCL/SDA internal pull-ups (boards have 10k on the shield)
  TWSR = 0;                      // prescaler 1
  TWBR = kTwbr;
  TWCR = _BV(TWEN);
}

bool Twi::busy() const { return g_busy; }

bool Twi::WaitIdle(uint32_t timeout_us) {
  if (!g_busy) return true;
  const uint32_t deadline = SystemClock().NowUs() + timeout_us;
  if (SleepUntil(deadline, [] { return !g_busy; })) return true;
  // Abort: reset the TWI (releases SCL/SDA), every unfinished transfer times out.
  cli();
  TWCR = 0;
  for (uint8_t i = g_index; i < g_count; ++i) g_ops[i].status = I2cStatus::kTimeout;
  g_index = g_count;
  g_phase = Phase::kIdle;
  g_busy = false;
  TWCR = _BV(TWEN);
  sei();
  if (timeouts_ != 0xFFFF) ++timeouts_;
  return false;
}

void Twi::Start(app::I2cTransfer* t, uint8_t count) {
  WaitIdle(kBatchTimeoutUs);
  g_wn = 0;  // a batch's writes (n = 0: a multiplexer select) have no data after the register
  Run(t, count);
}

void Twi::Run(app::I2cTransfer* t, uint8_t count) {
  for (uint8_t i = 0; i < count; ++i) t[i].status = I2cStatus::kTimeout;
  g_ops = t;
  g_count = count;
  g_index = 0;
  g_busy = true;
  cli();
  StartNext();
  sei();
}

void Twi::Wait() {
  WaitIdle(kBatchTimeoutUs);
  asm volatile("" ::: "memory");  // the interrupt's writes to the buffers are visible now
}

drivers::I2cStatus Twi::Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) {
  if (n == 0) return Write(addr7, reg, nullptr, 0);
  WaitIdle(kBatchTimeoutUs);  // a batch in flight finishes first
  g_single =
      app::I2cTransfer{addr7, reg, n, app::I2cTransfer::kNoDependency, buf, I2cStatus::kTimeout};
  g_wn = 0;
  Run(&g_single, 1);
  WaitIdle(kTransferTimeoutUs);
  asm volatile("" ::: "memory");
  return g_single.status;
}

drivers::I2cStatus Twi::Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) {
  WaitIdle(kBatchTimeoutUs);
  g_single = app::I2cTransfer{
      addr7, reg, 0, app::I2cTransfer::kNoDependency, nullptr, I2cStatus::kTimeout};
  g_wbuf = buf;
  g_wn = n;
  Run(&g_single, 1);
  WaitIdle(kTransferTimeoutUs);
  asm volatile("" ::: "memory");
  return g_single.status;
}

}  // namespace avr
}  // namespace ja

// Everything but the receive fast path: an interrupt handler of its own (full register save,
// reti), entered by a jump from TWI_vect. The name starts with __vector so avr-gcc accepts the
// signal attribute on it.
extern "C" void __vector_twi_slow(void) __attribute__((signal, used, externally_visible));
extern "C" void __vector_twi_slow(void) {
  ja::avr::IsrActivity a(ja::app::activity::kTwiIsr);
  ja::avr::OnTwi();
}

// The TWI interrupt. The steps of a transfer run in assembly (~40-110 cycles instead of ~125-230
// in C): byte received with ACK (0x50, the most frequent: checked first, r25 not saved) -> store
// it, receive the next (NACK for the last); (repeated) START sent -> send the SLA byte the C code
// prepared; SLA+W ACKed (0x18, or 0x28 from simavr 1.6) -> send the register; register ACKed in
// a read -> repeated START, in a write without data (a batch's multiplexer select) -> STOP and
// the next transfer; SLA+R ACKed -> receive; last byte (0x58) -> store it, STOP, start the
// next transfer (StartNext). NACKs, errors and the data bytes of writes jump to
// __vector_twi_slow (the C state machine, OnTwi) with the registers as they were at entry: all 19
// interrupts of a select + 8-byte read stay here. Phase numbers are Phase's (kStart 1, kSlaW 2,
// kWrite 3, kRepStart 4, kSlaR 5, kRead 6). Activity id 1 in GPIOR1 while it runs (the slow
// path sets it itself).
ISR(TWI_vect, ISR_NAKED) {
  asm volatile(
      "push r24                      \n\t"
      "in   r24, __SREG__            \n\t"
      "push r24                      \n\t"
      "push r23                      \n\t"
      "in   r23, %[gpior]            \n\t"  // interrupted activity
      "ldi  r24, %[id]               \n\t"
      "out  %[gpior], r24            \n\t"
      "lds  r24, %[twsr]             \n\t"
      "andi r24, 0xF8                \n\t"
      "cpi  r24, 0x50                \n\t"
      "brne 6f                       \n\t"
      // Byte received, ACK returned (the most frequent step: r25 not needed, not saved):
      // store it; ACK the next unless it is the last.
      "push r30                      \n\t"
      "push r31                      \n\t"
      "lds  r30, %[rptr]             \n\t"
      "lds  r31, %[rptr]+1           \n\t"
      "lds  r24, %[twdr]             \n\t"
      "st   Z+, r24                  \n\t"
      "sts  %[rptr], r30             \n\t"
      "sts  %[rptr]+1, r31           \n\t"
      "pop  r31                      \n\t"
      "pop  r30                      \n\t"
      "lds  r24, %[rleft]            \n\t"
      "dec  r24                      \n\t"  // bytes still to come
      "sts  %[rleft], r24            \n\t"
      "cpi  r24, 2                   \n\t"
      "ldi  r24, %[ack]              \n\t"  // ldi leaves the flags alone
      "brsh 5f                       \n\t"
      "ldi  r24, %[run]              \n\t"  // one left: NACK it
      "5:                            \n\t"
      "sts  %[twcr], r24             \n\t"
      "rjmp 82f                      \n\t"
      // Every other step needs r25 (the phase).
      "6:                            \n\t"
      "push r25                      \n\t"
      "lds  r25, %[phase]            \n\t"
      "cpi  r24, 0x08                \n\t"
      "breq 10f                      \n\t"
      "cpi  r24, 0x10                \n\t"
      "breq 10f                      \n\t"
      "cpi  r24, 0x18                \n\t"
      "breq 11f                      \n\t"
      "cpi  r24, 0x28                \n\t"
      "breq 12f                      \n\t"
      "cpi  r24, 0x40                \n\t"
      "breq 14f                      \n\t"
      "cpi  r24, 0x58                \n\t"
      "brne 7f                       \n\t"
      "rjmp 30f                      \n\t"
      "7:                            \n\t"
      "rjmp 90f                      \n\t"
      // (repeated) START sent, in kStart or kRepStart: the SLA byte, phase + 1.
      "10:                           \n\t"
      "cpi  r25, 1                   \n\t"
      "breq 1f                       \n\t"
      "cpi  r25, 4                   \n\t"
      "breq 7f                       \n\t"  // (90f is out of branch range)
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "1:                            \n\t"
      "inc  r25                      \n\t"
      "sts  %[phase], r25            \n\t"
      "lds  r24, %[sla]              \n\t"
      "sts  %[twdr], r24             \n\t"
      "ldi  r24, %[run]              \n\t"
      "rjmp 80f                      \n\t"
      // SLA+W ACKed (0x18) in kSlaW: the register.
      "11:                           \n\t"
      "cpi  r25, 2                   \n\t"
      "breq 7f                       \n\t"  // (90f is out of branch range)
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "13:                           \n\t"
      "ldi  r25, 3                   \n\t"
      "sts  %[phase], r25            \n\t"
      "lds  r24, %[reg]              \n\t"
      "sts  %[twdr], r24             \n\t"
      "ldi  r24, %[run]              \n\t"
      "rjmp 80f                      \n\t"
      // 0x28: SLA+W ACKed as simavr 1.6 reports it (kSlaW), or the register ACKed (kWrite):
      // in a read (bytes to receive) a repeated START, SLA+R next.
      "12:                           \n\t"
      "cpi  r25, 2                   \n\t"
      "breq 13b                      \n\t"
      "cpi  r25, 3                   \n\t"
      "breq 7f                       \n\t"  // (90f is out of branch range)
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "lds  r24, %[rleft]            \n\t"
      "tst  r24                      \n\t"
      "brne 7f                       \n\t"
      // A write (no bytes to receive) without data after the register (g_wn = 0: a batch's
      // multiplexer select): done, Finish(kOk, STOP) and StartNext as after the last byte of a
      // read (label 34); a write with data goes through the C code.
      "lds  r24, %[wn]               \n\t"
      "tst  r24                      \n\t"
      "breq 15f                      \n\t"
      "rjmp 90f                      \n\t"
      "15:                           \n\t"
      "push r30                      \n\t"
      "push r31                      \n\t"
      "push r22                      \n\t"
      "clr  r22                      \n\t"
      "rjmp 34f                      \n\t"
      "7:                            \n\t"
      "ldi  r25, 4                   \n\t"
      "sts  %[phase], r25            \n\t"
      "lds  r24, %[sla]              \n\t"
      "ori  r24, 1                   \n\t"
      "sts  %[sla], r24              \n\t"
      "ldi  r24, %[run_sta]          \n\t"
      "rjmp 80f                      \n\t"
      // SLA+R ACKed in kSlaR: receive, NACK at once if only one byte is wanted.
      "14:                           \n\t"
      "cpi  r25, 5                   \n\t"
      "breq 7f                       \n\t"  // (90f is out of branch range)
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "ldi  r25, 6                   \n\t"
      "sts  %[phase], r25            \n\t"
      "lds  r24, %[rleft]            \n\t"
      "cpi  r24, 2                   \n\t"
      "ldi  r24, %[ack]              \n\t"  // ldi leaves the flags alone
      "brsh 80f                      \n\t"
      "ldi  r24, %[run]              \n\t"  // one byte wanted: NACK it
      // Out: r24 = the TWCR value (81: TWCR already written; 82: r25 was not saved).
      "80:                           \n\t"
      "sts  %[twcr], r24             \n\t"
      "81:                           \n\t"
      "pop  r25                      \n\t"
      "82:                           \n\t"
      "out  %[gpior], r23            \n\t"
      "pop  r23                      \n\t"
      "pop  r24                      \n\t"
      "out  __SREG__, r24            \n\t"
      "pop  r24                      \n\t"
      "reti                          \n\t"
      // Last byte received, NACK returned (0x58), in kRead with it the one byte left: OnTwi's
      // kRead case, Finish(kOk, STOP) and StartNext written out (8 of the 84 interrupts of a
      // four-sensor batch; ~110 cycles instead of ~230 with the C handler's saves).
      "30:                           \n\t"
      "cpi  r25, 6                   \n\t"
      "breq 7f                       \n\t"
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "lds  r24, %[rleft]            \n\t"
      "cpi  r24, 1                   \n\t"
      "breq 7f                       \n\t"
      "rjmp 90f                      \n\t"
      "7:                            \n\t"
      "push r30                      \n\t"
      "push r31                      \n\t"
      "push r22                      \n\t"
      "lds  r30, %[rptr]             \n\t"  // *g_rptr++ = TWDR; g_rleft = 0
      "lds  r31, %[rptr]+1           \n\t"
      "lds  r24, %[twdr]             \n\t"
      "st   Z+, r24                  \n\t"
      "sts  %[rptr], r30             \n\t"
      "sts  %[rptr]+1, r31           \n\t"
      "clr  r22                      \n\t"  // 0 = kOk
      "sts  %[rleft], r22            \n\t"
      "34:                           \n\t"  // r22 = 0; r30, r31, r22 saved
      "lds  r25, %[index]            \n\t"  // Finish: g_ops[g_index].status = kOk
      "mov  r24, r25                 \n\t"
      "lsl  r24                      \n\t"
      "lsl  r24                      \n\t"
      "lsl  r24                      \n\t"
      "sub  r24, r25                 \n\t"  // 7 g_index (sizeof(I2cTransfer))
      "lds  r30, %[ops]              \n\t"
      "lds  r31, %[ops]+1            \n\t"
      "add  r30, r24                 \n\t"
      "adc  r31, r22                 \n\t"
      "std  Z+%[st_off], r22         \n\t"
      "inc  r25                      \n\t"  // ++g_index
      "sts  %[index], r25            \n\t"
      "ldi  r24, %[stop]             \n\t"  // STOP, then wait until it is out (<= 255 polls)
      "sts  %[twcr], r24             \n\t"
      "ldi  r22, 255                 \n\t"
      "31:                           \n\t"
      "lds  r24, %[twcr]             \n\t"
      "sbrs r24, %[twsto]            \n\t"
      "rjmp 32f                      \n\t"
      "dec  r22                      \n\t"
      "brne 31b                      \n\t"
      "32:                           \n\t"
      // StartNext: Z = &g_ops[g_index - 1], r25 = g_index.
      "33:                           \n\t"
      "lds  r24, %[count]            \n\t"
      "cp   r25, r24                 \n\t"
      "brsh 36f                      \n\t"
      "adiw r30, %[tsize]            \n\t"  // Z = &g_ops[g_index]
      "ldd  r24, Z+%[after_off]      \n\t"
      "cpi  r24, 0xFF                \n\t"  // kNoDependency
      "breq 35f                      \n\t"
      "push r26                      \n\t"  // the dependency's status: X = &g_ops[after]
      "push r27                      \n\t"
      "mov  r22, r24                 \n\t"
      "lsl  r24                      \n\t"
      "lsl  r24                      \n\t"
      "lsl  r24                      \n\t"
      "sub  r24, r22                 \n\t"
      "lds  r26, %[ops]              \n\t"
      "lds  r27, %[ops]+1            \n\t"
      "clr  r22                      \n\t"
      "add  r26, r24                 \n\t"
      "adc  r27, r22                 \n\t"
      "adiw r26, %[st_off]           \n\t"
      "ld   r24, X                   \n\t"
      "pop  r27                      \n\t"
      "pop  r26                      \n\t"
      "tst  r24                      \n\t"
      "breq 35f                      \n\t"
      "ldi  r24, %[bus_error]        \n\t"  // failed: this one kBusError, try the next
      "std  Z+%[st_off], r24         \n\t"
      "inc  r25                      \n\t"
      "sts  %[index], r25            \n\t"
      "rjmp 33b                      \n\t"
      "35:                           \n\t"  // start transfer Z: SLA+W after the START
      "clr  r22                      \n\t"
      "sts  %[pos], r22              \n\t"
      "ld   r24, Z                   \n\t"
      "lsl  r24                      \n\t"
      "sts  %[sla], r24              \n\t"
      "ldd  r24, Z+1                 \n\t"
      "sts  %[reg], r24              \n\t"
      "ldd  r24, Z+%[buf_off]        \n\t"
      "sts  %[rptr], r24             \n\t"
      "ldd  r24, Z+%[buf_off]+1      \n\t"
      "sts  %[rptr]+1, r24           \n\t"
      "ldd  r24, Z+2                 \n\t"
      "sts  %[rleft], r24            \n\t"
      "ldi  r24, 1                   \n\t"  // kStart
      "sts  %[phase], r24            \n\t"
      "ldi  r24, %[run_sta]          \n\t"
      "sts  %[twcr], r24             \n\t"
      "rjmp 37f                      \n\t"
      "36:                           \n\t"  // the list is done: idle
      "clr  r22                      \n\t"
      "sts  %[phase], r22            \n\t"
      "sts  %[busy], r22             \n\t"
      "37:                           \n\t"
      "pop  r22                      \n\t"
      "pop  r31                      \n\t"
      "pop  r30                      \n\t"
      "rjmp 81b                      \n\t"
      // Everything else: the C state machine, registers and activity as at entry.
      "90:                           \n\t"
      "pop  r25                      \n\t"
      "out  %[gpior], r23            \n\t"
      "pop  r23                      \n\t"
      "pop  r24                      \n\t"
      "out  __SREG__, r24            \n\t"
      "pop  r24                      \n\t"
      "jmp  __vector_twi_slow        \n\t" ::[twsr] "n"(_SFR_MEM_ADDR(TWSR)),
      [twdr] "n"(_SFR_MEM_ADDR(TWDR)), [twcr] "n"(_SFR_MEM_ADDR(TWCR)),
      [gpior] "I"(_SFR_IO_ADDR(GPIOR1)), [id] "M"(ja::app::activity::kTwiIsr),
      [rptr] "i"(&ja::avr::g_rptr), [rleft] "i"(&ja::avr::g_rleft), [phase] "i"(&ja::avr::g_phase),
      [sla] "i"(&ja::avr::g_sla), [reg] "i"(&ja::avr::g_reg),
      [run] "n"(_BV(TWINT) | _BV(TWEN) | _BV(TWIE)),
      [run_sta] "n"(_BV(TWINT) | _BV(TWEN) | _BV(TWIE) | _BV(TWSTA)),
      [ack] "n"(_BV(TWINT) | _BV(TWEN) | _BV(TWIE) | _BV(TWEA)),
      [stop] "n"(_BV(TWINT) | _BV(TWEN) | _BV(TWSTO)), [twsto] "n"(TWSTO),
      [ops] "i"(&ja::avr::g_ops), [index] "i"(&ja::avr::g_index), [count] "i"(&ja::avr::g_count),
      [pos] "i"(&ja::avr::g_pos), [busy] "i"(&ja::avr::g_busy), [wn] "i"(&ja::avr::g_wn),
      [tsize] "n"(sizeof(ja::app::I2cTransfer)),
      [after_off] "n"(offsetof(ja::app::I2cTransfer, after)),
      [buf_off] "n"(offsetof(ja::app::I2cTransfer, buf)),
      [st_off] "n"(offsetof(ja::app::I2cTransfer, status)),
      [bus_error] "n"(static_cast<uint8_t>(ja::drivers::I2cStatus::kBusError)));
}
