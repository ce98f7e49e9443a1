"""The registry of laser-rangefinder serial protocols (parsing and encoding live in
:mod:`~rigkit.rangefinder.trupulse` and :mod:`~rigkit.rangefinder.vectronix`, on the
shared types of :mod:`~rigkit.rangefinder.framing`).

Nothing there touches a port or a clock: every function maps bytes to values
(or values to bytes), so each protocol is testable with scripted bytes.

Two protocols with different shapes sit behind one seam (:class:`ProtocolSpec`):

``trupulse``
    Laser Technology TruPulse 200/360 (LTI "Criterion 400" / CR400 format,
    NMEA-0183 style): the device *pushes* ``$PLTIT,...*CS<CR><LF>`` sentences
    after each shot the user fires; XOR checksum; units feet, yards or metres.
``vectronix``
    Safran Vectronix LRF module ``>LM,...*CS<CR>`` command/response protocol
    (LRF 6019/6042/6742/7047 integrator manuals): the host must *request* each
    range; the module acknowledges, answers with up to five targets in
    centimetres and ends with a one-character prompt; additive checksum.

Frame layouts and the published example frames used as test vectors are from
the vendors' user/integrator manuals; see ``docs/rangefinder.md``.

Conventions: distances in metres, angles in degrees, inclination positive
above the horizontal, azimuth clockwise from north as the device reports it.
"""

from __future__ import annotations

from rigkit.errors import InputError
from rigkit.rangefinder.defaults import DEFAULT_BAUDS
from rigkit.rangefinder.framing import ProtocolSpec
from rigkit.rangefinder.trupulse import TRUPULSE_MAX_RANGE_M, parse_trupulse, split_trupulse
from rigkit.rangefinder.vectronix import (
    VECTRONIX_MAX_RANGE_M,
    parse_vectronix,
    split_vectronix,
    vectronix_frame,
)

PROTOCOLS: dict[str, ProtocolSpec] = {
    "trupulse": ProtocolSpec(
        name="trupulse",
        description="Laser Technology TruPulse 200/360 ($PLTIT sentences, 4800 baud 8N1)",
        default_baud=DEFAULT_BAUDS["trupulse"],
        split=split_trupulse,
        parse=parse_trupulse,
        # $GO fires the laser on TruPulse 360B-class firmware; others ignore it.
        request=b"$GO\r\n",
        request_by_default=False,
        min_request_interval_s=0.0,
        max_range_m=TRUPULSE_MAX_RANGE_M,
    ),
    "vectronix": ProtocolSpec(
        name="vectronix",
        description="Safran Vectronix LRF module (>LM,Md command/response)",
        default_baud=DEFAULT_BAUDS["vectronix"],
        split=split_vectronix,
        parse=parse_vectronix,
        request=vectronix_frame("LM,Md,3"),
        request_by_default=True,
        # The integrator manuals require the host to keep requests <= 2 Hz (eye safety).
        min_request_interval_s=0.5,
        max_range_m=VECTRONIX_MAX_RANGE_M,
    ),
}


def get_protocol(name: str) -> ProtocolSpec:
    """The :class:`ProtocolSpec` called ``name``; InputError naming the choices."""
    try:
        return PROTOCOLS[name]
    except KeyError:
        choices = ", ".join(sorted(PROTOCOLS))
        raise InputError(f"unknown rangefinder protocol {name!r} (choose {choices})") from None


def default_protocol(url: str) -> str:
    """The protocol to read ``url`` with when none is given: a simulator's own
    (``sim://vectronix?...`` speaks ``vectronix``), else ``trupulse``."""
    scheme, _, rest = url.partition("://")
    device = rest.split("?", 1)[0]
    return device if scheme == "sim" and device in PROTOCOLS else "trupulse"
