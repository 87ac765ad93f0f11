"""PCOMP, the composite shell property read ply by ply (MSC Nastran QRG, PCOMP); the
checks of CQUAD4, CTRIA3 and PSHELL are with the other fixed layouts
(:mod:`jaxfem.io._cards_checks`)."""

from __future__ import annotations

from ._bulkdata import Card
from ._fields import _id, _Raw, _re, _read

_PCOMP_FAILURE = ("HILL", "HOFF", "TSAI", "STRN")
_PCOMP_LAM_REFUSED = ("MEM", "BEND", "SMEAR", "SMCORE")


def _pcomp(raw: _Raw) -> list[Card]:
    """PCOMP: PID, Z0, NSM, SB, FT, TREF, GE, LAM; then plies MIDi, Ti, THETAi, SOUTi,
    two per continuation row (MSC QRG, PCOMP).

    ``MID``, ``T``, ``THETA`` [deg], ``SOUT`` are tuples over the plies as listed (LAM =
    SYM: the bottom half; the builder mirrors it). A blank MIDi or Ti takes the previous
    ply's value (QRG remark), so the first ply needs both; THETAi blank is 0.0, SOUTi NO.
    LAM blank or SYM only; an empty ply slot (decks written one ply per line) is no ply,
    as Nastran reads it; positions
    ``MIDi``, ``Ti``, ``THETAi``, ``SOUTi`` (i from 1, as listed) locate messages.
    """
    head = (_id("PID"), _re("Z0", None), _re("NSM"), _re("SB", None), ("FT", "word", None), _re("TREF"),
            _re("GE"), ("LAM", "word", None))
    values, positions = _read(raw, head)
    if values["FT"] is not None and values["FT"] not in _PCOMP_FAILURE:
        raise raw.error(positions["FT"], "FT", f"expected one of {', '.join(_PCOMP_FAILURE)}, got {values['FT']!r}")
    lam = values["LAM"]
    if lam in _PCOMP_LAM_REFUSED:
        raise raw.error(positions["LAM"], "LAM", f"LAM = {lam} is not supported (only blank or SYM)")
    if lam not in (None, "SYM"):
        raise raw.error(positions["LAM"], "LAM", f"expected blank, SYM, {', '.join(_PCOMP_LAM_REFUSED)}, got {lam!r}")
    mids: list[int] = []
    ts: list[float] = []
    thetas: list[float] = []
    souts: list[str] = []
    for i in range(8, len(raw.texts), 4):
        if not any(raw.text(j) for j in range(i, i + 4)):
            continue  # a blank ply slot (one ply per line) is no ply
        k = len(mids) + 1
        for j, key in ((i, "MID"), (i + 1, "T")):
            if k == 1 and not raw.text(j):
                raise raw.error(
                    j, f"{key}1", f"required field is blank (the first ply has no previous ply to take {key} from)"
                )
        mid = raw.get(i, f"MID{k}", "id", mids[-1] if mids else None)
        t = raw.get(i + 1, f"T{k}", "real", ts[-1] if ts else None)
        if t <= 0.0:
            raise raw.error(i + 1, f"T{k}", f"ply thickness must be > 0, got {t}")
        sout = raw.get(i + 3, f"SOUT{k}", "word", "NO")
        if sout not in ("YES", "NO"):
            raise raw.error(i + 3, f"SOUT{k}", f"expected YES or NO, got {sout!r}")
        mids.append(mid)
        ts.append(t)
        thetas.append(raw.get(i + 2, f"THETA{k}", "real", 0.0))
        souts.append(sout)
        positions.update({f"MID{k}": i, f"T{k}": i + 1, f"THETA{k}": i + 2, f"SOUT{k}": i + 3})
    if not mids:
        raise raw.error(8, "MID1", "PCOMP without plies")
    values.update(MID=tuple(mids), T=tuple(ts), THETA=tuple(thetas), SOUT=tuple(souts))
    positions.update(MID=8, T=9, THETA=10, SOUT=11)
    return [raw.card(values, positions)]
