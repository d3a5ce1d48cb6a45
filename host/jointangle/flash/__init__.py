"""Firmware images and how they reach a board: the UF2 format of the Raspberry Pi Pico (`uf2`)
and its BOOTSEL drive (`rp2_drive`). The Mega's avrdude command is in `jointangle.cli.flash`."""
