#include "platform/pico/board/i2c.hpp"

#include "platform/pico/board/clock.hpp"

namespace ja {
namespace pico {

namespace {

using drivers::I2cStatus;
using namespace hw;

constexpr uint32_t kTxLevel = 4;  // IC_TX_TL: TX_EMPTY when <= 4 commands are left to send
constexpr uint32_t kRxLevel = 7;  // IC_RX_TL: RX_FULL when >= 8 bytes wait

// Engine state: written by the interrupt while busy, by the main context only while idle (or
// with interrupts off).
app::I2cTransfer* g_ops = nullptr;
uint8_t g_count = 0;
uint8_t g_index = 0;
const uint8_t* g_wbuf = nullptr;  // blocking Write: the data after the register
uint8_t g_wn = 0;                 //
// The transfer in progress: commands queued of all (the register, then its reads or data
// bytes), reads queued, bytes received, abort sources seen.
uint16_t g_cmd_pos = 0;
uint16_t g_cmd_total = 0;
uint16_t g_reads_queued = 0;
uint16_t g_rx_pos = 0;
uint32_t g_abort = 0;
volatile bool g_busy = false;
app::I2cTransfer g_single;  // the blocking path's one transfer (n = 0: a write)
I2c0 g_i2c;

/// The block's configuration (it must be disabled): master, fast mode, repeated STARTs, no
/// slave; holds SCL rather than overrunning a full RX FIFO. Leaves it enabled, interrupts off.
void Configure() {
  Reg(kIcEnable) = 0;
  Reg(kIcCon) = kIcConMasterMode | kIcConSpeedFast | kIcConRestartEn | kIcConSlaveDisable |
                kIcConRxFifoFullHold;
  Reg(kIcFsSclHcnt) = i2c_timing::kHcnt;
  Reg(kIcFsSclLcnt) = i2c_timing::kLcnt;
  Reg(kIcFsSpklen) = i2c_timing::kSpklen;
  Reg(kIcSdaHold) = i2c_timing::kSdaTxHold;
  Reg(kIcTxTl) = kTxLevel;
  Reg(kIcRxTl) = kRxLevel;
  Reg(kIcIntrMask) = 0;
  Reg(kIcEnable) = 1;
}

/// The command word `i` of the current transfer `t` (0: the register).
inline uint32_t Command(const app::I2cTransfer& t, uint16_t i) {
  const uint32_t stop = (i + 1u == g_cmd_total) ? kIcCmdStop : 0u;
  if (i == 0) return t.reg | stop;
  if (t.n != 0) return kIcCmdRead | (i == 1 ? kIcCmdRestart : 0u) | stop;
  return g_wbuf[i - 1] | stop;
}

/// Queues the current transfer's commands while the TX FIFO has room and, for a read, the RX
/// FIFO can take every byte queued; then the interrupts that continue it: STOP_DET (it ended)
/// and TX_ABRT always, TX_EMPTY while commands wait for FIFO room, RX_FULL while they wait for
/// bytes to be drained.
void Feed(const app::I2cTransfer& t) {
  bool wait_rx = false;
  if (g_abort == 0) {
    uint32_t room = kIcFifoDepth - Reg(kIcTxflr);
    while (g_cmd_pos < g_cmd_total && room != 0) {
      if (t.n != 0 && g_cmd_pos != 0) {
        if (static_cast<uint32_t>(g_reads_queued - g_rx_pos) >= kIcFifoDepth) {
          wait_rx = true;
          break;
        }
        ++g_reads_queued;
      }
      Reg(kIcDataCmd) = Command(t, g_cmd_pos);
      ++g_cmd_pos;
      --room;
    }
  }
  uint32_t mask = kIcIntStopDet | kIcIntTxAbrt;
  if (g_abort == 0 && g_cmd_pos < g_cmd_total) mask |= wait_rx ? kIcIntRxFull : kIcIntTxEmpty;
  Reg(kIcIntrMask) = mask;
}

/// The received bytes into the transfer's buffer (never more than it asked for).
void Drain(const app::I2cTransfer& t) {
  for (uint32_t k = Reg(kIcRxflr); k != 0; --k) {
    const uint8_t b = static_cast<uint8_t>(Reg(kIcDataCmd));  // bits above 7: flags
    if (g_rx_pos < t.n) t.buf[g_rx_pos++] = b;
  }
}

/// Starts the next transfer whose dependency succeeded (the others get kBusError); idle at the
/// end of the list.
void StartNext() {
  while (g_index < g_count) {
    app::I2cTransfer& t = g_ops[g_index];
    if (t.after != app::I2cTransfer::kNoDependency && g_ops[t.after].status != I2cStatus::kOk) {
      t.status = I2cStatus::kBusError;
      ++g_index;
      continue;
    }
    Reg(kIcEnable) = 0;  // IC_TAR is written with the block disabled (the bus is idle here)
    Reg(kIcTar) = t.addr7;
    Reg(kIcEnable) = 1;
    ReadToClear(kIcClrIntr);  // the previous transfer's STOP_DET and abort
    g_cmd_pos = 0;
    g_cmd_total = static_cast<uint16_t>(1u + (t.n != 0 ? t.n : g_wn));
    g_reads_queued = 0;
    g_rx_pos = 0;
    g_abort = 0;
    Feed(t);
    return;
  }
  Reg(kIcIntrMask) = 0;
  g_busy = false;
}

/// The transfer's STOP went out: its status, then the next one.
void Finish(app::I2cTransfer& t) {
  I2cStatus st = I2cStatus::kOk;
  if (g_abort & (kIcAbrt7bAddrNoack | kIcAbrtTxdataNoack)) {
    st = I2cStatus::kNack;  // address or data not acknowledged
  } else if (g_abort != 0 || g_cmd_pos < g_cmd_total || g_rx_pos < t.n) {
    st = I2cStatus::kBusError;  // arbitration lost, or a STOP before the transfer's end
  }
  t.status = st;
  ++g_index;
  StartNext();
}

void OnI2c() {
  if (!g_busy) {
    Reg(kIcIntrMask) = 0;  // spurious
    return;
  }
  app::I2cTransfer& t = g_ops[g_index];
  const uint32_t stat = Reg(kIcIntrStat);
  if (stat & kIcIntTxAbrt) {
    // The controller flushed the TX FIFO and sends STOP (STOP_DET follows).
    g_abort |= Reg(kIcTxAbrtSource) | 0x80000000u;  // never 0 once aborted
    ReadToClear(kIcClrTxAbrt);
  }
  Drain(t);
  if (stat & kIcIntStopDet) {
    ReadToClear(kIcClrStopDet);
    Finish(t);
    return;
  }
  Feed(t);
}

}  // namespace

I2c0& SystemI2c() { return g_i2c; }

void I2c0::Init() {
  Configure();
  EnableIrq(kIrqI2c0);
}

bool I2c0::busy() const { return g_busy; }

bool I2c0::WaitIdle(uint32_t timeout_us) {
  if (!g_busy) return true;
  const uint32_t deadline = SystemClock().NowUs() + timeout_us;
  if (SleepUntil(deadline, [] { return !g_busy; })) return true;
  // Abort: ask the block to send STOP (IC_ENABLE.ABORT; enough unless a slave holds the bus),
  // then reset it (releases SCL/SDA whatever the bus does); every unfinished transfer stays
  // kTimeout.
  const uint32_t primask = SaveAndDisableInterrupts();
  Reg(kIcEnable) = kIcEnableEnable | kIcEnableAbort;
  SetBits(kResetsReset, kResetI2c0);
  ClearBits(kResetsReset, kResetI2c0);
  while (!(Reg(kResetsResetDone) & kResetI2c0)) {
  }
  Configure();
  Reg(kNvicIcpr) = 1u << kIrqI2c0;
  g_index = g_count;
  g_busy = false;
  RestoreInterrupts(primask);
  if (timeouts_ != 0xFFFF) ++timeouts_;
  return false;
}

void I2c0::Start(app::I2cTransfer* t, uint8_t count) {
  WaitIdle(kBatchTimeoutUs);
  g_wn = 0;  // a batch's writes (n = 0: a multiplexer select) have no data after the register
  Run(t, count);
}

void I2c0::Run(app::I2cTransfer* t, uint8_t count) {
  for (uint8_t i = 0; i < count; ++i) t[i].status = I2cStatus::kTimeout;
  g_ops = t;
  g_count = count;
  g_index = 0;
  g_busy = true;
  const uint32_t primask = SaveAndDisableInterrupts();
  StartNext();
  RestoreInterrupts(primask);
}

void I2c0::Wait() {
  WaitIdle(kBatchTimeoutUs);
  __asm volatile("" ::: "memory");  // the interrupt's writes to the buffers are visible now
}

drivers::I2cStatus I2c0::Read(uint8_t addr7, uint8_t reg, uint8_t* buf, uint8_t n) {
  if (n == 0) return Write(addr7, reg, nullptr, 0);
  WaitIdle(kBatchTimeoutUs);  // a batch in flight finishes first
  g_single =
      app::I2cTransfer{addr7, reg, n, app::I2cTransfer::kNoDependency, buf, I2cStatus::kTimeout};
  g_wn = 0;
  Run(&g_single, 1);
  WaitIdle(kTransferTimeoutUs);
  __asm volatile("" ::: "memory");
  return g_single.status;
}

drivers::I2cStatus I2c0::Write(uint8_t addr7, uint8_t reg, const uint8_t* buf, uint8_t n) {
  WaitIdle(kBatchTimeoutUs);
  g_single = app::I2cTransfer{
      addr7, reg, 0, app::I2cTransfer::kNoDependency, nullptr, I2cStatus::kTimeout};
  g_wbuf = buf;
  g_wn = n;
  Run(&g_single, 1);
  WaitIdle(kTransferTimeoutUs);
  __asm volatile("" ::: "memory");
  return g_single.status;
}

}  // namespace pico
}  // namespace ja

extern "C" void isr_i2c0() { ja::pico::OnI2c(); }
