// The RP2040 registers the Pico board uses, named as in the RP2040 datasheet (chapter and
// register names in the comments), plus the few Cortex-M0+ instructions and NVIC registers the
// board needs. Only what is used: this is not a full register map.
//
// Every APB/AHB peripheral register has atomic aliases (datasheet 2.1.2): +0x1000 XOR,
// +0x2000 set bits, +0x3000 clear bits. They are used for read-modify-write of control
// registers; never on registers with read side effects (IC_DATA_CMD, UARTDR) or write-1-to-clear
// ones (UARTICR, TIMER INTR), which take plain writes.
#pragma once

#include <stdint.h>

namespace ja {
namespace pico {
namespace hw {

inline volatile uint32_t& Reg(uint32_t addr) { return *reinterpret_cast<volatile uint32_t*>(addr); }
inline void SetBits(uint32_t addr, uint32_t mask) { Reg(addr + 0x2000u) = mask; }
inline void ClearBits(uint32_t addr, uint32_t mask) { Reg(addr + 0x3000u) = mask; }
/// A read for its side effect (the DW_apb_i2c's IC_CLR_* registers clear on read).
inline void ReadToClear(uint32_t addr) {
  const uint32_t value = Reg(addr);
  (void)value;
}

// ---- Clocks and resets (datasheet 2.14-2.18) ----
constexpr uint32_t kXoscHz = 12000000;  // the Pico's crystal
constexpr uint32_t kClkSysHz = 125000000;
constexpr uint32_t kClkPeriHz = kClkSysHz;  // clk_peri = clk_sys
constexpr uint32_t kClkRefHz = kXoscHz;

// RESETS (2.14): a block is held in reset while its bit in RESET is set; RESET_DONE says when
// its release has completed (the block's clock must run).
constexpr uint32_t kResetsBase = 0x4000C000;
constexpr uint32_t kResetsReset = kResetsBase + 0x0;
constexpr uint32_t kResetsResetDone = kResetsBase + 0x8;
constexpr uint32_t kResetI2c0 = 1u << 3;
constexpr uint32_t kResetIoBank0 = 1u << 5;
constexpr uint32_t kResetPadsBank0 = 1u << 8;
constexpr uint32_t kResetPllSys = 1u << 12;
constexpr uint32_t kResetTimer = 1u << 21;
constexpr uint32_t kResetUart0 = 1u << 22;

// PSM (2.13): WDSEL selects what a watchdog reset resets: everything but the two oscillators
// (bit 0 ROSC, bit 1 XOSC; 17 domains in all), as Raspberry Pi's SDK does.
constexpr uint32_t kPsmWdsel = 0x40010000 + 0x8;
constexpr uint32_t kPsmWdselAllButOscillators = 0x1FFFFu & ~0x3u;

// XOSC (2.16)
constexpr uint32_t kXoscBase = 0x40024000;
constexpr uint32_t kXoscCtrl = kXoscBase + 0x00;
constexpr uint32_t kXoscStatus = kXoscBase + 0x04;
constexpr uint32_t kXoscStartup = kXoscBase + 0x0C;
constexpr uint32_t kXoscCtrlFreqRange1To15MHz = 0xAA0;
constexpr uint32_t kXoscCtrlEnable = 0xFABu << 12;
constexpr uint32_t kXoscStatusStable = 1u << 31;

// PLL_SYS (2.18): f_out = f_ref / REFDIV * FBDIV / (POSTDIV1 * POSTDIV2).
constexpr uint32_t kPllSysBase = 0x40028000;
constexpr uint32_t kPllCs = kPllSysBase + 0x0;
constexpr uint32_t kPllPwr = kPllSysBase + 0x4;
constexpr uint32_t kPllFbdivInt = kPllSysBase + 0x8;
constexpr uint32_t kPllPrim = kPllSysBase + 0xC;
constexpr uint32_t kPllCsLock = 1u << 31;
constexpr uint32_t kPllPwrPd = 1u << 0;
constexpr uint32_t kPllPwrPostdivPd = 1u << 3;
constexpr uint32_t kPllPwrVcoPd = 1u << 5;

// CLOCKS (2.15): each generator has CTRL, DIV (INT in bits 31:8, FRAC 7:0) and SELECTED (one
// bit per SRC of a glitchless mux, set once the mux has switched).
constexpr uint32_t kClocksBase = 0x40008000;
constexpr uint32_t kClkRefCtrl = kClocksBase + 0x30;
constexpr uint32_t kClkRefDiv = kClocksBase + 0x34;
constexpr uint32_t kClkRefSelected = kClocksBase + 0x38;
constexpr uint32_t kClkSysCtrl = kClocksBase + 0x3C;
constexpr uint32_t kClkSysDiv = kClocksBase + 0x40;
constexpr uint32_t kClkSysSelected = kClocksBase + 0x44;
constexpr uint32_t kClkPeriCtrl = kClocksBase + 0x48;
constexpr uint32_t kClkSysResusCtrl = kClocksBase + 0x78;
constexpr uint32_t kClkDivOne = 1u << 8;
constexpr uint32_t kClkRefSrcRosc = 0;  // CLK_REF_CTRL.SRC (bits 1:0)
constexpr uint32_t kClkRefSrcXosc = 2;
constexpr uint32_t kClkSysSrcRef = 0;  // CLK_SYS_CTRL.SRC (bit 0)
constexpr uint32_t kClkSysSrcAux = 1;
constexpr uint32_t kClkSysAuxsrcMask = 7u << 5;  // CLK_SYS_CTRL.AUXSRC: 0 = clksrc_pll_sys
constexpr uint32_t kClkPeriEnable = 1u << 11;    // CLK_PERI_CTRL.ENABLE; AUXSRC 0 = clk_sys

// ---- GPIO (2.19) ----
constexpr uint32_t kIoBank0Base = 0x40014000;
constexpr uint32_t IoGpioCtrl(uint32_t gpio) { return kIoBank0Base + 0x04 + 8 * gpio; }
constexpr uint32_t kFuncUart = 2;  // GPIOx_CTRL.FUNCSEL
constexpr uint32_t kFuncI2c = 3;
constexpr uint32_t kPadsBank0Base = 0x4001C000;
constexpr uint32_t PadsGpio(uint32_t gpio) { return kPadsBank0Base + 0x04 + 4 * gpio; }
constexpr uint32_t kPadSchmitt = 1u << 1;
constexpr uint32_t kPadPullDown = 1u << 2;
constexpr uint32_t kPadPullUp = 1u << 3;
constexpr uint32_t kPadDrive4mA = 1u << 4;
constexpr uint32_t kPadInputEnable = 1u << 6;

// ---- TIMER (4.6): a 64-bit microsecond counter from the watchdog's tick; ALARM0 fires
// TIMER_IRQ_0 when the low 32 bits equal it. ----
constexpr uint32_t kTimerBase = 0x40054000;
constexpr uint32_t kTimerAlarm0 = kTimerBase + 0x10;
constexpr uint32_t kTimerArmed = kTimerBase + 0x20;
constexpr uint32_t kTimerRawL = kTimerBase + 0x28;
constexpr uint32_t kTimerIntr = kTimerBase + 0x34;
constexpr uint32_t kTimerInte = kTimerBase + 0x38;
constexpr uint32_t kTimerAlarm0Bit = 1u << 0;

// ---- WATCHDOG (4.7) ----
constexpr uint32_t kWatchdogBase = 0x40058000;
constexpr uint32_t kWatchdogCtrl = kWatchdogBase + 0x00;
constexpr uint32_t kWatchdogLoad = kWatchdogBase + 0x04;
constexpr uint32_t kWatchdogReason = kWatchdogBase + 0x08;
constexpr uint32_t kWatchdogTick = kWatchdogBase + 0x2C;
constexpr uint32_t kWatchdogCtrlTrigger = 1u << 31;
constexpr uint32_t kWatchdogCtrlEnable = 1u << 30;
constexpr uint32_t kWatchdogCtrlPauseDebug = (1u << 26) | (1u << 25) | (1u << 24);
constexpr uint32_t kWatchdogReasonTimer = 1u << 0;
constexpr uint32_t kWatchdogReasonForce = 1u << 1;
constexpr uint32_t kWatchdogTickEnable = 1u << 9;

// ---- UART0 (4.2, an ARM PL011) ----
constexpr uint32_t kUart0Base = 0x40034000;
constexpr uint32_t kUartDr = kUart0Base + 0x000;
constexpr uint32_t kUartFr = kUart0Base + 0x018;
constexpr uint32_t kUartIbrd = kUart0Base + 0x024;
constexpr uint32_t kUartFbrd = kUart0Base + 0x028;
constexpr uint32_t kUartLcrH = kUart0Base + 0x02C;
constexpr uint32_t kUartCr = kUart0Base + 0x030;
constexpr uint32_t kUartIfls = kUart0Base + 0x034;
constexpr uint32_t kUartImsc = kUart0Base + 0x038;
constexpr uint32_t kUartMis = kUart0Base + 0x040;
constexpr uint32_t kUartIcr = kUart0Base + 0x044;
constexpr uint32_t kUartFrBusy = 1u << 3;
constexpr uint32_t kUartFrRxfe = 1u << 4;
constexpr uint32_t kUartFrTxff = 1u << 5;
constexpr uint32_t kUartLcrHFen = 1u << 4;
constexpr uint32_t kUartLcrHWlen8 = 3u << 5;
constexpr uint32_t kUartCrUarten = 1u << 0;
constexpr uint32_t kUartCrTxe = 1u << 8;
constexpr uint32_t kUartCrRxe = 1u << 9;
constexpr uint32_t kUartIntRx = 1u << 4;  // UARTIMSC/MIS/ICR bits
constexpr uint32_t kUartIntTx = 1u << 5;
constexpr uint32_t kUartIntRt = 1u << 6;
constexpr uint32_t kUartIntErrors = 0xFu << 7;  // framing, parity, break, overrun
constexpr uint32_t kUartIntAll = 0x7FFu;

// ---- I2C0 (4.3, a Synopsys DW_apb_i2c; 16-entry TX and RX FIFOs) ----
constexpr uint32_t kI2c0Base = 0x40044000;
constexpr uint32_t kIcCon = kI2c0Base + 0x00;
constexpr uint32_t kIcTar = kI2c0Base + 0x04;
constexpr uint32_t kIcDataCmd = kI2c0Base + 0x10;
constexpr uint32_t kIcFsSclHcnt = kI2c0Base + 0x1C;
constexpr uint32_t kIcFsSclLcnt = kI2c0Base + 0x20;
constexpr uint32_t kIcIntrStat = kI2c0Base + 0x2C;
constexpr uint32_t kIcIntrMask = kI2c0Base + 0x30;
constexpr uint32_t kIcRxTl = kI2c0Base + 0x38;
constexpr uint32_t kIcTxTl = kI2c0Base + 0x3C;
constexpr uint32_t kIcClrIntr = kI2c0Base + 0x40;
constexpr uint32_t kIcClrTxAbrt = kI2c0Base + 0x54;
constexpr uint32_t kIcClrStopDet = kI2c0Base + 0x60;
constexpr uint32_t kIcEnable = kI2c0Base + 0x6C;
constexpr uint32_t kIcTxflr = kI2c0Base + 0x74;
constexpr uint32_t kIcRxflr = kI2c0Base + 0x78;
constexpr uint32_t kIcSdaHold = kI2c0Base + 0x7C;
constexpr uint32_t kIcTxAbrtSource = kI2c0Base + 0x80;
constexpr uint32_t kIcFsSpklen = kI2c0Base + 0xA0;
constexpr uint32_t kIcFifoDepth = 16;
constexpr uint32_t kIcEnableEnable = 1u << 0;
constexpr uint32_t kIcEnableAbort = 1u << 1;
// IC_CON
constexpr uint32_t kIcConMasterMode = 1u << 0;
constexpr uint32_t kIcConSpeedFast = 2u << 1;
constexpr uint32_t kIcConRestartEn = 1u << 5;
constexpr uint32_t kIcConSlaveDisable = 1u << 6;
constexpr uint32_t kIcConRxFifoFullHold = 1u << 9;
// IC_DATA_CMD: data in bits 7:0; reads may carry FIRST_DATA_BYTE above them (bit 11 on the
// chip, bit 10 in rp2040js 1.4.1), so received bytes are masked with 0xFF.
constexpr uint32_t kIcCmdRead = 1u << 8;
constexpr uint32_t kIcCmdStop = 1u << 9;
constexpr uint32_t kIcCmdRestart = 1u << 10;
// IC_INTR_STAT / IC_INTR_MASK
constexpr uint32_t kIcIntRxFull = 1u << 2;
constexpr uint32_t kIcIntTxEmpty = 1u << 4;
constexpr uint32_t kIcIntTxAbrt = 1u << 6;
constexpr uint32_t kIcIntStopDet = 1u << 9;
// IC_TX_ABRT_SOURCE
constexpr uint32_t kIcAbrt7bAddrNoack = 1u << 0;
constexpr uint32_t kIcAbrtTxdataNoack = 1u << 3;

// ---- Cortex-M0+ (ARMv6-M) ----
constexpr uint32_t kNvicIser = 0xE000E100;
constexpr uint32_t kNvicIcer = 0xE000E180;
constexpr uint32_t kNvicIcpr = 0xE000E280;
constexpr uint32_t kIrqTimer0 = 0;  // datasheet 2.3.2 "Interrupts"
constexpr uint32_t kIrqUart0 = 20;
constexpr uint32_t kIrqI2c0 = 23;

inline void EnableIrq(uint32_t irq) {
  Reg(kNvicIcpr) = 1u << irq;
  Reg(kNvicIser) = 1u << irq;
}
inline void DisableIrq(uint32_t irq) { Reg(kNvicIcer) = 1u << irq; }

/// PRIMASK saved and set (interrupts off); RestoreInterrupts(saved) puts it back.
inline uint32_t SaveAndDisableInterrupts() {
  uint32_t primask;
  __asm volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
  return primask;
}
inline void RestoreInterrupts(uint32_t primask) {
  __asm volatile("msr primask, %0" ::"r"(primask) : "memory");
}
/// Sleeps until an event: any interrupt (its return sets the event register, so one that ran
/// since the last WFE makes this one return at once), or returns at once if one is registered.
inline void WaitForEvent() { __asm volatile("wfe" ::: "memory"); }

// ---- Flash (the Pico's 2 MB W25Q16JV behind the XIP window) ----
constexpr uint32_t kXipBase = 0x10000000;
constexpr uint32_t kFlashBytes = 2u * 1024 * 1024;
constexpr uint32_t kFlashSectorBytes = 4096;
constexpr uint32_t kFlashPageBytes = 256;

}  // namespace hw
}  // namespace pico
}  // namespace ja
