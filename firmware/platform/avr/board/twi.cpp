#include "platform/avr/board/twi.hpp"

#include <avr/interrupt.h>
#include <avr/io.h>

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

// Engine state: written by the interrupt while busy, by the main context only while idle.
app::I2cTransfer* g_ops = nullptr;
uint8_t g_count = 0;
uint8_t g_index = 0;
uint8_t g_pos = 0;                // bytes written after the register / bytes read
const uint8_t* g_wbuf = nullptr;  // blocking Write: the data after the register
uint8_t g_wn = 0;                 //
volatile Phase g_phase = Phase::kIdle;
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
  switch (g_phase) {
    case Phase::kStart:
      if (st != kStart && st != kRepStart) return Finish(I2cStatus::kBusError, false);
      TWDR = static_cast<uint8_t>(t.addr7 << 1);  // SLA+W
      g_phase = Phase::kSlaW;
      return Go(0);
    case Phase::kSlaW:
      // 0x28/0x30 here: simavr 1.6 reports SLA+W like a data byte (SENSORS.md D2).
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
      return Go(t.n > 1 ? _BV(TWEA) : 0);  // NACK the last byte
    case Phase::kRead:
      if (st != kRxAck && st != kRxNack) return Finish(I2cStatus::kBusError, false);
      t.buf[g_pos++] = TWDR;
      if (st == kRxNack || g_pos >= t.n) return Finish(I2cStatus::kOk, true);
      return Go(g_pos + 1 < t.n ? _BV(TWEA) : 0);
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
  Start(&g_single, 1);
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
  Start(&g_single, 1);
  WaitIdle(kTransferTimeoutUs);
  asm volatile("" ::: "memory");
  return g_single.status;
}

}  // namespace avr
}  // namespace ja

ISR(TWI_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kTwiIsr);
  ja::avr::OnTwi();
}
