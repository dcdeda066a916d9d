"""The bus load rule of the node (mirror of ``att_node_bus_load``) and the table of docs/can.md."""

from __future__ import annotations


def classic_bits(n: int) -> int:
    """Worst-case bits of a classic frame with n data bytes, 11-bit ID, incl. 3 bits intermission."""
    n = min(n, 8)
    return 8 * n + 47 + (34 + 8 * n - 1) // 4


def fd_frame_time(n: int, bitrate: int, data_bitrate: int) -> float:
    """Worst-case time in s of a CAN FD frame with n data bytes (11-bit ID, bit rate switch)."""
    n = min(n, 64)
    crc = 21 if n > 16 else 17
    stuff = (22 + 8 * n - 1) // 4
    nominal = 17 + 4 + 1 + 2 + 7 + 3
    data = 5 + 8 * n + (stuff - 4) + 4 + crc + (1 + (3 + crc) // 4)
    return nominal / bitrate + data / data_bitrate


def bus_load(
    sample_rate: float,
    bitrate: int = 500_000,
    data_bitrate: int = 0,
    fd: bool = False,
    output_divider: int = 1,
    diag_divider: int = 16,
    accel_out: bool = False,
    mag_offset: bool = False,
) -> float:
    """Fraction of the bus time used by the node's outputs (mirror of ``att_node_bus_load``, in float64).

    ``mag_offset``: the filter estimates a hard-iron offset (mars, or a mekf with its magnetometer, with
    ``hard_iron_tau`` > 0), so an ATT_MAG_OFFSET follows every ATT_DIAG.
    """
    t_classic = classic_bits(8) / bitrate
    t_set = fd_frame_time(64, bitrate, data_bitrate) if fd else 6 * t_classic
    if accel_out:  # ATT_LIN_ACC + ATT_EARTH_ACC (classic) or ATT_ACCEL_FD after every set
        t_set += fd_frame_time(64, bitrate, data_bitrate) if fd else 2 * t_classic
    if diag_divider:
        t_set += (2 if mag_offset else 1) * t_classic / diag_divider
    return sample_rate / output_divider * t_set


def input_bus_load(
    sample_rate: float, bitrate: int = 500_000, data_bitrate: int = 0, fd: bool = False
) -> float:
    """Fraction of the bus time used by the IMU input frames (3 classic or 1 IMU_FD per sample)."""
    t = fd_frame_time(64, bitrate, data_bitrate) if fd else 3 * classic_bits(8) / bitrate
    return sample_rate * t


BUS_TABLE_RATES = (50.0, 100.0, 200.0, 285.714, 500.0, 1000.0, 2000.0)
"""Output rates (Hz) of the bus load table in docs/can.md."""


BUS_TABLE_COLUMNS = (
    ("classic 500k", 500_000, 0, False),
    ("classic 1M", 1_000_000, 0, False),
    ("FD 500k/2M", 500_000, 2_000_000, True),
    ("FD 500k/5M", 500_000, 5_000_000, True),
    ("FD 1M/2M", 1_000_000, 2_000_000, True),
    ("FD 1M/5M", 1_000_000, 5_000_000, True),
)
"""Bus configurations (name, nominal bit/s, data bit/s, fd) of the bus load table in docs/can.md."""


def bus_load_table(with_inputs: bool = False, accel_out: bool = False) -> str:
    """The markdown bus load table of docs/can.md (outputs only, or outputs + IMU inputs), DIAG every 16th."""
    head = "| output rate | " + " | ".join(name for name, *_ in BUS_TABLE_COLUMNS) + " |"
    rule = "|---|" + "---|" * len(BUS_TABLE_COLUMNS)
    rows = [head, rule]
    for rate in BUS_TABLE_RATES:
        cells = []
        for _, br, dbr, fd in BUS_TABLE_COLUMNS:
            out = bus_load(rate, br, dbr, fd, accel_out=accel_out)
            load = out + (input_bus_load(rate, br, dbr, fd) if with_inputs else 0.0)
            refused = " **refused**" if out > 1.0 else ""
            cells.append(f"{100 * load:.1f} %{refused}")
        rows.append(f"| {rate:g} Hz | " + " | ".join(cells) + " |")
    return "\n".join(rows)
