#include "platform/pico/board/chip.hpp"

#include "platform/pico/board/rp2040.hpp"

namespace ja {
namespace pico {

namespace {

using namespace hw;

// PLL_SYS: 12 MHz / REFDIV 1 * FBDIV 125 = 1500 MHz VCO (within 750..1600), / 6 / 2 = 125 MHz.
constexpr uint32_t kPllRefdiv = 1;
constexpr uint32_t kPllFbdiv = 125;
constexpr uint32_t kPllPostdiv1 = 6;
constexpr uint32_t kPllPostdiv2 = 2;
static_assert(kXoscHz / kPllRefdiv * kPllFbdiv / (kPllPostdiv1 * kPllPostdiv2) == kClkSysHz,
              "PLL_SYS gives clk_sys");
static_assert(kXoscHz / kPllRefdiv * kPllFbdiv >= 750000000u &&
                  kXoscHz / kPllRefdiv * kPllFbdiv <= 1600000000u,
              "VCO within 750..1600 MHz");

// XOSC start-up wait: STARTUP.DELAY counts 256 crystal cycles: (12000 kHz + 128) / 256 = 47,
// ~1 ms (the figure Raspberry Pi's SDK uses for the Pico's crystal).
constexpr uint32_t kXoscStartupDelay = (kXoscHz / 1000 + 128) / 256;

// The watchdog tick: clk_ref cycles per tick, 1 us (TIMER counts these ticks).
constexpr uint32_t kTickCycles = kClkRefHz / 1000000;
static_assert(kTickCycles * 1000000 == kClkRefHz && kTickCycles < 512, "a 1 us tick");

// The blocks the board uses (PLL_SYS is reset on its own, before it is configured).
constexpr uint32_t kUsedBlocks =
    kResetIoBank0 | kResetPadsBank0 | kResetTimer | kResetUart0 | kResetI2c0;

// RP2040-E1: the watchdog counter decrements twice per tick, so the load is 2 per us.
constexpr uint32_t kWatchdogTicksPerMs = 2000;
constexpr uint32_t kWatchdogMaxMs = 0xFFFFFFu / kWatchdogTicksPerMs;  // 8388 ms

uint32_t g_watchdog_load = 0;
ResetReason g_reset_reason = ResetReason::kPowerOn;

void WaitFor(uint32_t addr, uint32_t mask, uint32_t value) {
  while ((Reg(addr) & mask) != value) {
  }
}

/// Holds `blocks` in reset, then releases them and waits until they are out.
void ResetBlocks(uint32_t blocks) {
  SetBits(kResetsReset, blocks);
  ClearBits(kResetsReset, blocks);
  WaitFor(kResetsResetDone, blocks, blocks);
}

void StartCrystal() {
  Reg(kXoscStartup) = kXoscStartupDelay;
  Reg(kXoscCtrl) = kXoscCtrlEnable | kXoscCtrlFreqRange1To15MHz;
  WaitFor(kXoscStatus, kXoscStatusStable, kXoscStatusStable);
}

/// The datasheet's PLL sequence (2.18.2): reset, dividers, power up the VCO, wait for lock,
/// then the post dividers and their power.
void StartPllSys() {
  ResetBlocks(kResetPllSys);
  Reg(kPllCs) = kPllRefdiv;
  Reg(kPllFbdivInt) = kPllFbdiv;
  ClearBits(kPllPwr, kPllPwrPd | kPllPwrVcoPd);
  WaitFor(kPllCs, kPllCsLock, kPllCsLock);
  Reg(kPllPrim) = (kPllPostdiv1 << 16) | (kPllPostdiv2 << 12);
  ClearBits(kPllPwr, kPllPwrPostdivPd);
}

void StartClocks() {
  Reg(kClkSysResusCtrl) = 0;
  // clk_sys and clk_ref off any aux source first: a warm start (a debugger's reset of the core)
  // may find clk_sys on PLL_SYS, which is about to be reset.
  ClearBits(kClkSysCtrl, 1u);  // SRC = clk_ref
  WaitFor(kClkSysSelected, 0x3u, 1u << kClkSysSrcRef);
  ClearBits(kClkRefCtrl, 3u);  // SRC = ROSC
  WaitFor(kClkRefSelected, 0x7u, 1u << kClkRefSrcRosc);

  StartCrystal();
  StartPllSys();

  // clk_ref = XOSC, undivided.
  Reg(kClkRefDiv) = kClkDivOne;
  Reg(kClkRefCtrl) = kClkRefSrcXosc;
  WaitFor(kClkRefSelected, 0x7u, 1u << kClkRefSrcXosc);
  // clk_sys = PLL_SYS: the aux mux (not selected now) to clksrc_pll_sys, then the glitchless
  // mux to aux.
  Reg(kClkSysDiv) = kClkDivOne;
  ClearBits(kClkSysCtrl, kClkSysAuxsrcMask);
  SetBits(kClkSysCtrl, kClkSysSrcAux);
  WaitFor(kClkSysSelected, 0x3u, 1u << kClkSysSrcAux);
  // clk_peri = clk_sys (no glitchless mux: stopped while its source changes).
  Reg(kClkPeriCtrl) = 0;
  for (volatile int i = 0; i < 8; ++i) {
  }
  Reg(kClkPeriCtrl) = kClkPeriEnable;

  Reg(kWatchdogTick) = kWatchdogTickEnable | kTickCycles;
}

void StartPins() {
  // Pads first (input enabled, 4 mA, Schmitt trigger), then the function.
  const uint32_t pad = kPadInputEnable | kPadDrive4mA | kPadSchmitt;
  Reg(PadsGpio(0)) = pad | kPadPullDown;  // UART0 TX: the reset default
  Reg(PadsGpio(1)) = pad | kPadPullUp;    // UART0 RX: idle high with no adapter attached
  Reg(PadsGpio(4)) = pad | kPadPullUp;    // I2C0 SDA (the modules' pull-ups do the real work)
  Reg(PadsGpio(5)) = pad | kPadPullUp;    // I2C0 SCL
  Reg(IoGpioCtrl(0)) = kFuncUart;
  Reg(IoGpioCtrl(1)) = kFuncUart;
  Reg(IoGpioCtrl(4)) = kFuncI2c;
  Reg(IoGpioCtrl(5)) = kFuncI2c;
}

}  // namespace

void InitChip() {
  const uint32_t reason = Reg(kWatchdogReason);
  g_reset_reason = (reason & kWatchdogReasonTimer)   ? ResetReason::kWatchdogTimeout
                   : (reason & kWatchdogReasonForce) ? ResetReason::kWatchdogTrigger
                                                     : ResetReason::kPowerOn;
  Reg(kWatchdogCtrl) = kWatchdogCtrlPauseDebug;  // off until WatchdogStart
  StartClocks();
  ResetBlocks(kUsedBlocks);
  StartPins();
}

ResetReason LastResetReason() { return g_reset_reason; }

void WatchdogStart(uint32_t ms) {
  if (ms > kWatchdogMaxMs) ms = kWatchdogMaxMs;
  Reg(kPsmWdsel) = kPsmWdselAllButOscillators;
  g_watchdog_load = ms * kWatchdogTicksPerMs;
  Reg(kWatchdogLoad) = g_watchdog_load;
  Reg(kWatchdogCtrl) = kWatchdogCtrlEnable | kWatchdogCtrlPauseDebug;
}

void WatchdogKick() { Reg(kWatchdogLoad) = g_watchdog_load; }

void WatchdogKickFor(uint32_t ms) {
  if (ms > kWatchdogMaxMs) ms = kWatchdogMaxMs;
  Reg(kWatchdogLoad) = ms * kWatchdogTicksPerMs;
}

void WatchdogReboot() {
  Reg(kPsmWdsel) = kPsmWdselAllButOscillators;
  SetBits(kWatchdogCtrl, kWatchdogCtrlTrigger);
  for (;;) {
    __asm volatile("" ::: "memory");
  }
}

}  // namespace pico
}  // namespace ja
