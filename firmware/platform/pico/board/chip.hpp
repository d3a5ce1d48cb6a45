// The RP2040's bring-up (datasheet 2.14-2.19): the 12 MHz crystal, PLL_SYS at 125 MHz, the clock
// generators, the watchdog's 1 us tick, the blocks the board uses out of reset and the Pico's
// pins on their functions; and the watchdog (4.7) with the reason for the last reset.
#pragma once

#include <stdint.h>

namespace ja {
namespace pico {

/// XOSC 12 MHz; PLL_SYS 12 MHz / 1 * 125 = 1500 MHz VCO, / 6 / 2 = 125 MHz; clk_ref = XOSC,
/// clk_sys = PLL_SYS (through the aux mux, switched glitch-free), clk_peri = clk_sys; the
/// watchdog tick = clk_ref / 12 = 1 MHz (it also drives TIMER: 1 count per us); IO_BANK0,
/// PADS_BANK0, TIMER, UART0 and I2C0 reset and released; GP0/GP1 = UART0 TX/RX (function 2,
/// RX pulled up), GP4/GP5 = I2C0 SDA/SCL (function 3, pulled up). Call first, with no
/// interrupt enabled. Also stops a watchdog left running and records the reset reason.
void InitChip();

enum class ResetReason : uint8_t {
  kPowerOn = 0,      // power-on or the RUN pin (WATCHDOG REASON = 0)
  kWatchdogTimeout,  // the watchdog was not kicked in time
  kWatchdogTrigger,  // CTRL.TRIGGER: System::Reboot (the reset command)
};
/// Why the chip last reset, as WATCHDOG REASON said at InitChip.
ResetReason LastResetReason();

/// Starts (or restarts) the watchdog with a timeout of `ms` (1..8000); a watchdog reset resets
/// everything but the two oscillators (PSM WDSEL).
void WatchdogStart(uint32_t ms);
/// Reloads the timeout WatchdogStart set.
void WatchdogKick();
/// Reloads once with a longer timeout (`ms`, up to 8000) for one long operation (a flash sector
/// erase); the next WatchdogKick goes back to the normal one.
void WatchdogKickFor(uint32_t ms);
/// Resets the chip now through the watchdog (CTRL.TRIGGER).
[[noreturn]] void WatchdogReboot();

}  // namespace pico
}  // namespace ja
