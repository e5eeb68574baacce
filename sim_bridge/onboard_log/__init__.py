"""The vehicle's own DataFlash log (.BIN).

- dataflash: the DataFlash format, written by our own encoder
- logger: the log folder, its files and their rotation, as AP_Logger keeps them
"""
