// The CMake image's entry point (jointangle_mega2560.elf); the Arduino sketch calls BoardMain()
// from setup() instead (firmware/sketches/JointAngle).
#include "platform/avr/board/board.hpp"

int main() { ja::avr::BoardMain(); }
