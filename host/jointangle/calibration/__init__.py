"""Sensor calibration: â = S v + o per accelerometer (Woods & Vikas, Appendix IV).

- `fit`: the maths — linear least squares over known poses (Appendix IV), the fixture-free
  gravity-magnitude fit (Madgwick §6.2.1) and alignment to the link (Madgwick §6.2.2).
- `stillness`: still segments found automatically in a stream; noise measured in them.
- `pipeline`: from a recording to a per-sensor report with grades and rejection reasons, and a
  calibrated rig.
"""
