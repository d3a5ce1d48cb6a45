// The Arduino Mega 2560 board (ATmega2560, 16 MHz): the app (firmware/app) over Timer1
// (clock.hpp), USART0 (uart.hpp), TWI0 (twi.hpp), avr-libc's EEPROM and the watchdog.
// BoardMain() never returns; the CMake image's main() and the Arduino sketch's setup() call it.
#pragma once

namespace ja {
namespace avr {

/// Initialises the hardware, runs App::Begin (watchdog 1 s), then the loop: kick the watchdog
/// (250 ms), App::Poll, sleep until the next period or a received byte.
[[noreturn]] void BoardMain();

}  // namespace avr
}  // namespace ja
