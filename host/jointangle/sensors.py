"""Facts about the supported accelerometer models (datasheet figures, docs/sensors.md §A).

Only what the host needs: valid ranges, the size of one count, and the datasheet noise density
used when a rig file does not state one.
"""

from __future__ import annotations

from dataclasses import dataclass

STANDARD_GRAVITY = 9.80665  # m/s² per g


@dataclass(frozen=True)
class SensorModel:
    """Static description of one accelerometer part."""

    name: str
    ranges_g: tuple[int, ...]
    noise_density_ug: tuple[float, float, float]  # µg/√Hz on x, y, z
    has_gyro: bool

    def lsb_mps2(self, range_g: int) -> float:
        """Size of one output count in m/s² at the given range."""
        if self.name == "adxl345":
            # Full resolution keeps ~3.9 mg/LSB at every range (datasheet, docs/sensors.md §A1).
            return 0.0039 * STANDARD_GRAVITY
        if self.name == "adxl357":
            # 51200 / 25600 / 12800 LSB/g at ±10 / ±20 / ±40 g: 20-bit over ±range.
            lsb_per_g = {10: 51200.0, 20: 25600.0, 40: 12800.0}[range_g]
            return STANDARD_GRAVITY / lsb_per_g
        if self.name == "bno055":
            # UNIT_SEL accel in m/s²: 1 m/s² = 100 LSB.
            return 0.01
        raise ValueError(f"unknown sensor model {self.name!r}")


SENSOR_MODELS: dict[str, SensorModel] = {
    "adxl345": SensorModel("adxl345", (2, 4, 8, 16), (290.0, 290.0, 430.0), has_gyro=False),
    "adxl357": SensorModel("adxl357", (10, 20, 40), (80.0, 80.0, 80.0), has_gyro=False),
    # BNO055's accelerometer is a BMA-family part; 150 µg/√Hz is Bosch's typical figure.
    "bno055": SensorModel("bno055", (2, 4, 8, 16), (150.0, 150.0, 150.0), has_gyro=True),
}
