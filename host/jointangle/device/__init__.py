"""The board's view of things, as the host reconstructs it: what its hello and status say, the
rig and sensor choice its filter runs on, its fixed-point calibration of raw counts, and its
estimates checked against the host's float `mirror`.

- `describe`: hello and status in words (names, EEPROM warnings, the sustainable rate).
- `calibration_map`: the firmware's float32 m/s² per count and its Q15.16 calibration map.
- `rig`: the rig as the firmware's filter sees it, which sensors it filters, its geometry.
- `verify`: firmware θ against `mirror`, per filter run (`replay --verify`, `live`).

Shared by `live`, `recording`, `calibration`, `i2c` and the command line; it imports none of
them.
"""
