// The Raspberry Pi Pico board (RP2040, core 0 at 125 MHz): the app (firmware/app) over TIMER
// (clock.hpp), UART0 (uart.hpp), I2C0 (i2c.hpp), the last flash sector as its EEPROM
// (flash_store.hpp) and the watchdog (chip.hpp). BoardMain() never returns; the image's main()
// calls it.
#pragma once

namespace ja {
namespace pico {

/// Initialises the chip and the peripherals, runs App::Begin (watchdog 1 s), then the loop:
/// kick the watchdog (250 ms), App::Poll, sleep until the next period or a received byte.
[[noreturn]] void BoardMain();

}  // namespace pico
}  // namespace ja
