"""Physical constants, each defined once.

``G0_MPS2``: standard gravity (ISO 80000-3), the ISA's ``g0``, ArduPilot's
``GRAVITY_MSS`` and the unit behind MAVLink's milli-g accelerations
(RAW_IMU, SCALED_IMU*). The local gravity the filters subtract is a setting
(``sensors.ins.gravity_mps2``) whose default is this value.
"""

G0_MPS2 = 9.80665
