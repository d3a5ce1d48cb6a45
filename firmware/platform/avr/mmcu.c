/* simavr's MCU description block (.mmcu section, placed at 0x910000 by the linker options):
 * lets firmware/sim/avr_cycles pick the core and clock from the ELF. C, not C++: avr-g++ 5.4
 * rejects the C99 designated initialisers in AVR_MCU(). */
#include "avr_mcu_section.h"
AVR_MCU(F_CPU, "atmega2560");
