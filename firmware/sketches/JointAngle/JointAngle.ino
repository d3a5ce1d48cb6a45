// jointangle firmware for the Arduino Mega 2560 (ATmega2560, 16 MHz) as an Arduino sketch.
// The firmware lives in the repository (firmware/app, drivers, protocol, core and
// firmware/platform/avr/board); src/ holds one small file per firmware source that includes it
// through the include path, so nothing is copied. The include path needs three directories
// (firmware/platform/avr/README.md): <repo>/firmware, <repo>/firmware/platform/avr/include (the
// freestanding C++ headers Eigen needs on avr-gcc) and Eigen 3.4.
//
// The board owns the hardware: Timer1, USART0 at 500 000 baud, TWI at 400 kHz, the watchdog.
// Do not use Serial, Wire, millis() or delay() alongside it.
#include "platform/avr/board/board.hpp"

void setup() { ja::avr::BoardMain(); }  // never returns

void loop() {}
