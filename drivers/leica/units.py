"""The emScon unit enumerations as numbers: from cellcal's units (mm, rad, °C, hPa, %RH) and back.

emScon reports every value in the server's *current* units, which any client
may change (``SetUnits``) and which persist on the server. The driver sets its
own (:data:`DRIVER_UNITS`); the simulator converts to whatever is set.
"""

from __future__ import annotations

import math
from collections.abc import Container

from drivers.leica.enums import (
    ES_AngleUnit,
    ES_HumidityUnit,
    ES_LengthUnit,
    ES_PressureUnit,
    ES_TemperatureUnit,
)

#: length unit -> how many of it make one millimetre
PER_MM = {
    ES_LengthUnit.ES_LU_Meter: 1e-3,
    ES_LengthUnit.ES_LU_Millimeter: 1.0,
    ES_LengthUnit.ES_LU_Micron: 1e3,
    ES_LengthUnit.ES_LU_Foot: 1.0 / 304.8,
    ES_LengthUnit.ES_LU_Yard: 1.0 / 914.4,
    ES_LengthUnit.ES_LU_Inch: 1.0 / 25.4,
}

#: angle unit -> how many of it make one radian
PER_RAD = {
    ES_AngleUnit.ES_AU_Radian: 1.0,
    ES_AngleUnit.ES_AU_Degree: 180.0 / math.pi,
    ES_AngleUnit.ES_AU_Gon: 200.0 / math.pi,
}

#: pressure unit -> how many of it make one hPa (mbar = hPa; inH2O at 4 °C)
PER_HPA = {
    ES_PressureUnit.ES_PU_Mbar: 1.0,
    ES_PressureUnit.ES_PU_HPascal: 1.0,
    ES_PressureUnit.ES_PU_KPascal: 0.1,
    ES_PressureUnit.ES_PU_MmHg: 100.0 / 133.322387415,
    ES_PressureUnit.ES_PU_Psi: 100.0 / 6894.757293168,
    ES_PressureUnit.ES_PU_InH2O: 100.0 / 249.08891,
    ES_PressureUnit.ES_PU_InHg: 100.0 / 3386.389,
}

#: (length, angle, temperature, pressure, humidity) the driver works in
DRIVER_UNITS = (
    ES_LengthUnit.ES_LU_Millimeter,
    ES_AngleUnit.ES_AU_Radian,
    ES_TemperatureUnit.ES_TU_Celsius,
    ES_PressureUnit.ES_PU_HPascal,
    ES_HumidityUnit.ES_HU_RH,
)

#: the units a freshly started server reports in the simulator (metres, degrees, mbar)
SERVER_DEFAULT_UNITS = (
    ES_LengthUnit.ES_LU_Meter,
    ES_AngleUnit.ES_AU_Degree,
    ES_TemperatureUnit.ES_TU_Celsius,
    ES_PressureUnit.ES_PU_Mbar,
    ES_HumidityUnit.ES_HU_RH,
)


def temp_from_c(t_c: float, unit: int) -> float:
    """°C → ``unit`` (ES_TemperatureUnit)."""
    return t_c * 9.0 / 5.0 + 32.0 if unit == ES_TemperatureUnit.ES_TU_Fahrenheit else t_c


def temp_to_c(t: float, unit: int) -> float:
    """``unit`` (ES_TemperatureUnit) → °C."""
    return (t - 32.0) * 5.0 / 9.0 if unit == ES_TemperatureUnit.ES_TU_Fahrenheit else t


def valid_units(units: tuple[int, int, int, int, int]) -> int:
    """0 when every unit is known, else the 1-based index of the first unknown one."""
    tables: tuple[Container[int], ...] = (PER_MM, PER_RAD, (0, 1), PER_HPA, (0,))
    for k, (u, table) in enumerate(zip(units, tables, strict=True)):
        if u not in table:
            return k + 1
    return 0
