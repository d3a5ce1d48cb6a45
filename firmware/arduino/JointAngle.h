// The jointangle firmware as an Arduino library (firmware/arduino/README.md): the sketch
// includes this header and calls ja::avr::BoardMain() from setup(); the board owns Timer1,
// USART0 at 500 000 baud, TWI at 400 kHz and the watchdog, so do not use Serial, Wire, millis()
// or delay() alongside it.
#ifndef JOINTANGLE_ARDUINO_LIBRARY_H
#define JOINTANGLE_ARDUINO_LIBRARY_H

#include "platform/avr/board/board.hpp"

#endif  // JOINTANGLE_ARDUINO_LIBRARY_H
