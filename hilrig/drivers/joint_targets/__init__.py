"""Joint targets to the robot over Modbus: ``wire`` (the register map; pure), ``frame`` (the RTU
request filled in place by a compiled kernel) and ``link`` (the pipelined Modbus writer)."""
