"""CDR codec of the contract's messages: ready bytes to publish and values read from raw bytes.

The nodes publish ``Float64MultiArray`` and ``std_msgs/String`` messages as ready CDR
bytes and read the raw bytes of their subscriptions directly, without rclpy's conversion
to and from message objects (the largest cost of plant_sim, feed and the EMS node per
step; docs/ros_tools.md "Profile of a step"). Little-endian CDR (encapsulation CDR_LE)
only; every function here is checked against rclpy's own serialisation in the tests.
No rclpy here.
"""

from __future__ import annotations

import struct
import sys
from array import array


def cdr_prefix(label: str, n: int) -> bytes:
    """Serialise the head of a ``Float64MultiArray``: its CDR bytes up to its ``n`` float64 values.

    One dimension ``label``, size and stride ``n``, data offset 0, little endian
    (encapsulation CDR_LE). Layout (alignment counted after the 4-byte encapsulation
    header): dimension count; label length (with the terminating NUL), label, NUL, padding
    to 4; size; stride; data offset; value count; padding to 8; then the values. Equal to
    rclpy's serialisation (test/test_ros_node_base.py).

    Parameters
    ----------
    label : str
        Label of the one layout dimension.
    n : int
        Number of values.

    Returns
    -------
    bytes
        The prefix; append the values as little-endian float64 to get the message.

    Raises
    ------
    RuntimeError
        On a big-endian machine.
    """
    if sys.byteorder != "little":  # array.tobytes() is native: CDR_LE needs little endian
        raise RuntimeError("ready CDR bytes need a little-endian machine")
    body = bytearray(struct.pack("<I", 1))
    raw = label.encode("utf-8") + b"\0"
    body += struct.pack("<I", len(raw)) + raw
    body += b"\0" * (-len(body) % 4)
    body += struct.pack("<III", n, n, 0)
    body += struct.pack("<I", n)
    body += b"\0" * (-len(body) % 8)
    return b"\x00\x01\x00\x00" + bytes(body)


def string_cdr(text: str) -> bytes:
    """Serialise a ``std_msgs/String`` to CDR bytes, as rclpy does, without the message object.

    Encapsulation CDR_LE, length with the NUL, UTF-8 bytes, NUL (test/test_ros_node_base.py).

    Parameters
    ----------
    text : str
        The string.

    Returns
    -------
    bytes
        The serialised message.
    """
    raw = text.encode("utf-8")
    return b"\x00\x01\x00\x00" + (len(raw) + 1).to_bytes(4, "little") + raw + b"\0"


def uint32_cdr(value: int) -> bytes:
    """Serialise a ``std_msgs/UInt32`` (``plant/step``) to CDR bytes: encapsulation CDR_LE, the value.

    Parameters
    ----------
    value : int
        The value, 0 .. 2**32 - 1.

    Returns
    -------
    bytes
        The serialised message.

    Raises
    ------
    ValueError
        For a value outside 0 .. 2**32 - 1.
    """
    if not 0 <= value < 2**32:
        raise ValueError(f"UInt32 out of range: {value}")
    return b"\x00\x01\x00\x00" + value.to_bytes(4, "little")


def clock_cdr(t_ns: int) -> bytes:
    """Serialise a ``rosgraph_msgs/Clock`` to CDR bytes.

    Its ``builtin_interfaces/Time`` as int32 ``sec`` and uint32 ``nanosec``, CDR_LE.

    Parameters
    ----------
    t_ns : int
        The time [ns since the epoch].

    Returns
    -------
    bytes
        The ``Clock`` message as CDR bytes.

    Raises
    ------
    ValueError
        For a time whose seconds do not fit an int32.
    """
    sec, nanosec = divmod(t_ns, 1_000_000_000)
    if not -(2**31) <= sec < 2**31:
        raise ValueError(f"Clock out of range: {t_ns} ns")
    return b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nanosec)


def _array_data(raw: bytes) -> tuple[int, int]:
    """Locate the values of a CDR ``Float64MultiArray``: ``(byte offset, count)`` (labels skipped).

    Raises
    ------
    ValueError
        For bytes that are not a little-endian ``Float64MultiArray`` or are cut short.
    """
    if len(raw) < 8 or raw[1] != 1:
        raise ValueError("not a little-endian CDR Float64MultiArray")
    unpack = struct.unpack_from
    try:
        pos = 4
        (ndim,) = unpack("<I", raw, pos)
        pos += 4
        for _ in range(ndim):
            (n_label,) = unpack("<I", raw, pos)
            pos += 4 + n_label
            pos += -(pos - 4) % 4
            pos += 8  # size, stride
        pos += 4  # data_offset
        (n,) = unpack("<I", raw, pos)
    except struct.error:
        raise ValueError(f"Float64MultiArray cut short ({len(raw)} bytes)") from None
    pos += 4
    pos += -(pos - 4) % 8
    if pos + 8 * n > len(raw):
        raise ValueError(f"Float64MultiArray of {n} values cut short ({len(raw)} bytes)")
    return pos, n


def parse_array(raw: bytes) -> array:
    """Read the values of a CDR-serialised ``Float64MultiArray`` (any layout dimensions).

    Reads the little-endian CDR directly (dimension labels skipped), without rclpy's
    conversion to a message object (docs/ros_tools.md "Profile of a step").

    Parameters
    ----------
    raw : bytes
        The serialised message.

    Returns
    -------
    array.array
        The values as ``array('d')``, in the units of the topic's layout.

    Raises
    ------
    ValueError
        For bytes that are not a little-endian ``Float64MultiArray`` or are cut short.
    """
    pos, n = _array_data(raw)
    out = array("d")
    out.frombytes(raw[pos:pos + 8 * n])
    return out


def array_step(raw: bytes) -> int:
    """Read element 0 of a CDR ``Float64MultiArray``: the step of every contract array topic.

    Parameters
    ----------
    raw : bytes
        A contract array message as CDR bytes.

    Returns
    -------
    int
        Its step.

    Raises
    ------
    ValueError
        For bytes that are not such an array, or an empty one.
    """
    pos, n = _array_data(raw)
    if n < 1:
        raise ValueError("empty Float64MultiArray: no step")
    return int(struct.unpack_from("<d", raw, pos)[0])


def uint32_value(raw: bytes) -> int:
    """Read the value of a CDR ``std_msgs/UInt32`` (e.g. ``plant/step``).

    Parameters
    ----------
    raw : bytes
        A ``UInt32`` message as CDR bytes.

    Returns
    -------
    int
        The value, 0 .. 2**32 - 1.

    Raises
    ------
    ValueError
        For bytes cut short.
    """
    try:
        return int(struct.unpack_from("<I", raw, 4)[0])
    except struct.error:
        raise ValueError("UInt32 cut short") from None
