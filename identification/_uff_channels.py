"""Dataset-58 function types, and the channels of channel-only records mapped to DoFs.

Channel-only exports write node 0, direction 0 and a channel name; the name read is the
response entity name (record 6 field 5; pyuff ``rsp_ent_name``), for a time record the
ID line 1 (``id1``) when that is blank or NONE; the excitation of an FRF is named by
the reference entity name (record 6 field 8, ``ref_ent_name``).
"""

from __future__ import annotations

_TIME = 1  # dataset 58 function type: time response
_FRF, _COHERENCE = 4, 6  # dataset 58 function types
_NO_NAME = ("", "NONE")  # pyuff writes NONE for an absent entity name


def _channel_name(record: dict, role: str) -> str:
    """The channel name of a record's response (``"rsp"``) or reference (``"ref"``)."""
    name = str(record.get(f"{role}_ent_name", "")).strip()
    if name.upper() in _NO_NAME and role == "rsp" and int(record["func_type"]) == _TIME:
        name = str(record.get("id1", "")).strip()
    return "" if name.upper() in _NO_NAME else name


def _mapped(records: list[tuple[int, dict]], dof_map: dict | None, path: str, funcs: tuple[int, ...]):
    """The dataset-58 records with the DoFs of ``dof_map`` {channel: (node, direction)}
    (a row overrides the DoF written in the record). Raises ``ValueError`` for a row that
    names no channel of the file, and for a record of a function type in ``funcs`` whose
    channel has no DoF (direction 0) and no row."""
    from ._time_data import check_dof_map

    dof_map = None if dof_map is None else check_dof_map(dof_map)
    names, out, unmapped = set(), [], []
    for number, r in records:
        func = int(r["func_type"])
        if func not in (_TIME, _FRF, _COHERENCE):
            out.append((number, r))
            continue
        r = dict(r)
        for role in ("rsp",) if func == _TIME else ("rsp", "ref"):
            name = _channel_name(r, role)
            names.add(name)
            if dof_map and name in dof_map:
                r[f"{role}_node"], r[f"{role}_dir"] = dof_map[name]
            elif func in funcs and int(r[f"{role}_dir"]) == 0 and name:  # unnamed: refused by the reader
                unmapped.append(repr(name))
        out.append((number, r))
    names.discard("")
    if dof_map:
        absent = [c for c in dof_map if c not in names]
        if absent:
            raise ValueError(f"{path}: DoF map rows name channel(s) {', '.join(map(repr, absent))} absent from the "
                             f"file; its channels are {', '.join(map(repr, sorted(names))) or 'unnamed'}")
    if unmapped:
        unmapped = list(dict.fromkeys(unmapped))
        listing = ", ".join(unmapped[:20]) + (f" and {len(unmapped) - 20} more" if len(unmapped) > 20 else "")
        what = "time-history" if funcs == (_TIME,) else "FRF"
        if dof_map:
            raise ValueError(f"{path}: {what} channel(s) {listing} have no DoF in the file (direction 0) "
                             "and no row in the DoF map")
        raise ValueError(f"{path}: {what} records have no DoF (direction 0) for channel(s) {listing}: map "
                         "the channels to DoFs (dof_map; jaxfem: --dof-map CSV with columns channel,node,direction)")
    return out
