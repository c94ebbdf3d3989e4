"""Hardware adapters: Kobuki over serial, RPLIDAR A1, UVC camera (and their protocol emulators)."""
