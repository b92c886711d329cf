"""The Kunwei six-axis F/T sensor: ``wire`` (frames, framer; pure), ``link`` (the serial port,
polled) and ``gravity`` (the tool's weight, tare and compensation)."""
