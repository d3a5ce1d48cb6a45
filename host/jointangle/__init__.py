"""jointangle: joint angles from accelerometer arrays (Woods & Vikas), host side.

Importing this package has no side effects; the command line lives in `jointangle.cli`.
"""

__version__ = "0.1.0"
