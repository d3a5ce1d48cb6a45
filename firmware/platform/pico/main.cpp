// The Pico image's entry point (jointangle_pico.elf): the board (board/board.hpp) runs the app.
#include "platform/pico/board/board.hpp"

int main() { ja::pico::BoardMain(); }
