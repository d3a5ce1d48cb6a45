"""The host driver for boards without a microcontroller (issue 7, item 3): TCA9548A + ADXL345 /
ADXL357 / BNO055 read directly from a Linux I2C bus with smbus2, the rig's calibration and the
float EKF on the host.

- `devices`: the parts' register sequences (combined write-read transactions via i2c_rdwr).
- `bus`: `--i2c N` (/dev/i2c-N) or `--i2c sim` (the virtual devices at real 400 kHz timing).
- `pipeline`: bus → calibration → EKF per step, each stage timed; faults as status bits.
- `live`: `jointangle live --i2c BUS`.
"""
