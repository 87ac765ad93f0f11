"""The cards of real Nastran decks: each read alike from free, small and large field, each
malformed one a located error; GRDSET defaults, DMIG matrices, PBEAM/PBEAML stations,
scalar points, shared rigid element ids."""

import re
import warnings

import pytest

from jaxfem.io import PBARL_DIMENSIONS, BulkDataError, read_bdf_text


def _formats(name: str, fields: list[str]) -> tuple[str, str, str]:
    """Free, small and large field text of one card from its data fields ('' blank)."""
    rows = [fields[i:i + 8] for i in range(0, len(fields), 8)]
    free = "".join(f"{name if k == 0 else ''},{','.join(r)}\n" for k, r in enumerate(rows))
    small = "".join(f"{name if k == 0 else '+':<8}" + "".join(f"{f:<8}" for f in r).rstrip() + "\n"
                    for k, r in enumerate(rows))
    large = ""
    for k, r in enumerate(rows):
        r = r + [""] * (8 - len(r))
        large += f"{name + '*' if k == 0 else '*':<8}" + "".join(f"{f:<16}" for f in r[:4]).rstrip() + "\n"
        large += "*       " + "".join(f"{f:<16}" for f in r[4:]).rstrip() + "\n"
    return free, small, large


CARDS = [
    ("SPCADD", ["10", "1", "2", "3", "4", "5", "6", "7", "8", "9"], {"SID": 10, "S": tuple(range(1, 10))}),
    ("MPCADD", ["5", "1", "", "2"], {"SID": 5, "S": (1, 2)}),
    ("GRDSET", ["", "3", "", "", "", "1", "345", "2"], {"CP": 3, "CD": 1, "PS": 345, "SEQID": 2}),
    ("SPOINT", ["1", "THRU", "5", "9"], {"ID": (1, 2, 3, 4, 5, 9)}),
    ("CORD1R", ["1", "10", "11", "12", "2", "10", "12", "11"], {"CID": 1, "G1": 10, "G2": 11, "G3": 12}),
    ("CORD1C", ["3", "10", "11", "12"], {"CID": 3, "G3": 12}),
    ("CORD1S", ["4", "12", "11", "10"], {"CID": 4, "G1": 12}),
    ("CORD2C", ["5", "", "0.", "0.", "0.", "0.", "0.", "1.", "1.", "0.", "0."], {"CID": 5, "RID": 0, "B3": 1.0, "C1": 1.0}),
    ("CORD2S", ["6", "5", "1.", "0.", "0.", "1.", "0.", "1.", "2.", "0.", "0."], {"RID": 5, "A1": 1.0, "C1": 2.0}),
    ("CONROD", ["1", "1", "2", "3", "1.5", "2.5", "0.1", "0.2"], {"MID": 3, "A": 1.5, "J": 2.5, "C": 0.1, "NSM": 0.2}),
    ("CONM1", ["1", "2", "", "1.", "", "2.", "", "", "3.", "", "", "", "4.", "", "", "", "", "5.", "", "", "", "",
               "", "6."], {"G": 2, "CID": 0, "M11": 1.0, "M22": 2.0, "M33": 3.0, "M44": 4.0, "M55": 5.0, "M66": 6.0,
                          "M21": 0.0}),
    ("CMASS1", ["1", "", "5", "1", "6", "2"], {"PID": 1, "G1": 5, "C1": 1, "G2": 6, "C2": 2}),
    ("CMASS2", ["2", "1.5", "5"], {"M": 1.5, "G1": 5, "C1": 0, "G2": None, "C2": None}),
    ("CMASS3", ["3", "7", "100", "0"], {"PID": 7, "S1": 100, "S2": None}),
    ("CMASS4", ["4", "2.5", "100", "101"], {"M": 2.5, "S1": 100, "S2": 101}),
    ("PMASS", ["7", "1.", "8", "2.", "", "", "9", "3."], {"PID": 7, "M": 1.0}),
    ("CELAS3", ["5", "", "", "101"], {"PID": 5, "S1": None, "S2": 101}),
    ("CELAS4", ["6", "1.+5", "100"], {"K": 1e5, "S1": 100, "S2": None}),
    ("CDAMP1", ["1", "9", "5", "3", "", ""], {"PID": 9, "G1": 5, "C1": 3, "G2": None}),
    ("CDAMP2", ["2", "0.5", "5", "3", "100", "0"], {"B": 0.5, "G2": 100, "C2": 0}),
    ("CDAMP3", ["3", "9", "100", "101"], {"PID": 9, "S2": 101}),
    ("CDAMP4", ["4", "1.-2", "", "101"], {"B": 0.01, "S1": None}),
    ("PDAMP", ["9", "1.", "", "", "10", "2."], {"PID": 9, "B": 1.0}),
    ("CVISC", ["7", "", "1", "2"], {"PID": 7, "G1": 1, "G2": 2}),
    ("PVISC", ["3", "6.2", "3.94", "", "4", "1."], {"PID": 3, "CE": 6.2, "CR": 3.94}),
    ("RBAR", ["1", "1", "2", "123456", "", "", "", "6.5-6", "20."], {"CNA": 123456, "CNB": None, "CMA": None,
                                                                   "ALPHA": 6.5e-6, "TREF": 20.0}),
    ("RROD", ["2", "1", "2", "", "3", "1.-5"], {"CMA": None, "CMB": 3, "ALPHA": 1e-5}),
    ("RBE1", ["3", "1", "123", "2", "456", "", "", "", "UM", "3", "123456", "4", "12", "", "", "", "", "5", "3",
              "1.-6"], {"GN": (1, 2), "CN": (123, 456), "GM": (3, 4, 5), "CM": (123456, 12, 3), "ALPHA": 1e-6}),
    ("SUPORT", ["1", "123456", "100", "", "2", "12"], {"ID": 1, "C": 123456}),
    ("SUPORT1", ["4", "1", "12", "100", "0"], {"SID": 4, "ID": 1, "C": 12}),
    ("EIGRL", ["10", "0.", "100.", "6", "", "", "", "MAX", "NUMS=2"], {"SID": 10, "V1": 0.0, "V2": 100.0, "ND": 6,
                                                                     "NORM": "MAX", "OPTIONS": ("NUMS=2",)}),
    ("EIGR", ["11", "", "0.", "50.", "", "10", "", "", "MAX"], {"METHOD": "LAN", "F2": 50.0, "ND": 10, "NORM": "MAX"}),
    ("PBEAML", ["1", "2", "", "I", "", "", "", "", "1.", "2.", "3.", "4.", "5.", "6.", "0.5", "NO", "0.5", "", "",
                "", "", "", "", "", "YES", "1.", "2.", "4.", "6.", "8.", "10.", "12."],
     {"TYPE": "I", "GROUP": "MSCBML0", "XXB": (0.0, 0.5, 1.0), "NSM": (0.5, 0.5, 0.5),
      "DIMS": ((1.0, 2.0, 3.0, 4.0, 5.0, 6.0), (1.5, 3.0, 4.5, 6.0, 7.5, 9.0), (2.0, 4.0, 6.0, 8.0, 10.0, 12.0))}),
]
COUNTS = {"CORD1R": 2, "PMASS": 3, "PDAMP": 2, "PVISC": 2, "SUPORT": 3, "SUPORT1": 2}


@pytest.mark.parametrize("name, fields, expected", CARDS, ids=[c[0] for c in CARDS])
def test_new_cards_in_free_small_and_large_field(name, fields, expected):
    free, small, large = (read_bdf_text(text, name="m.bdf") for text in _formats(name, fields))
    assert free.cards == small.cards == large.cards and not free.unknown
    cards = free[name]
    assert len(cards) == COUNTS.get(name, 1)
    assert {k: cards[0][k] for k in expected} == expected
    assert free.card_status() == {name: "read"}


def test_split_cards_keep_their_own_ids():
    bulk = read_bdf_text("PMASS,7,1.,8,2.,,,9,3.\nSUPORT,1,123456,100,,2,12\nCORD1R,1,10,11,12,2,10,12,11\n")
    assert [(p.id, p["M"]) for p in bulk["PMASS"]] == [(7, 1.0), (8, 2.0), (9, 3.0)]
    assert [(s["ID"], s["C"]) for s in bulk["SUPORT"]] == [(1, 123456), (100, 0), (2, 12)]
    assert [(c.id, c["G2"]) for c in bulk["CORD1R"]] == [(1, 11), (2, 12)]
    (spoint,) = read_bdf_text("SPOINT,1,THRU,99999999\n", name="m.bdf")["SPOINT"]
    assert spoint["ID"].runs == ((1, 99999999),) and spoint.where("ID") == "m.bdf:1: SPOINT field 2 (ID)"


def test_dmig_in_three_formats_symmetric_and_square():
    cards = [("DMIG", ["KAAX", "0", "6", "2"]), ("DMIG", ["KAAX", "1", "1", "", "1", "1", "1.+3", "", "2", "1", "-5.+2"]),
             ("DMIG", ["MSQ", "0", "1", "1"]), ("DMIG", ["KAAX", "2", "1", "", "2", "1", "1.+3"]),
             ("DMIG", ["MSQ", "100", "", "", "100", "", "2.", "", "1", "3", "0.5"]),
             ("DMIG", ["MSQ", "1", "3", "", "100", "0", "0.5"])]
    texts = [_formats(n, f) for n, f in cards]
    free, small, large = (read_bdf_text("".join(t[k] for t in texts)) for k in range(3))
    assert free.cards == small.cards == large.cards
    kaax, msq = free["DMIG"]
    assert (kaax.id, kaax["IFO"], kaax["TIN"], kaax.line) == ("KAAX", 6, 2, 1)
    assert kaax["ENTRIES"] == ((1, 1, 1, 1, 1e3), (1, 1, 2, 1, -500.0), (2, 1, 2, 1, 1e3))
    assert (msq["IFO"], msq["ENTRIES"]) == (1, ((100, 0, 100, 0, 2.0), (100, 0, 1, 3, 0.5), (1, 3, 100, 0, 0.5)))


@pytest.mark.parametrize("kind, n", sorted(PBARL_DIMENSIONS.items()))
def test_pbarl_every_library_type(kind, n):
    dims = [f"{k + 1}." for k in range(n)]
    free, small, large = (read_bdf_text(t) for t in _formats("PBARL", ["3", "1", "", kind, "", "", "", ""] + dims
                                                              + ["0.25"]))
    assert free.cards == small.cards == large.cards
    (card,) = free["PBARL"]
    assert [card[f"DIM{k + 1}"] for k in range(n)] == [float(k + 1) for k in range(n)] and card["NSM"] == 0.25


def test_pbarl_dbox_defaults():
    (box,) = read_bdf_text("PBARL,3,1,,DBOX\n,10.,5.,3.,1.,,2.\n")["PBARL"]
    assert [box[f"DIM{k}"] for k in range(1, 11)] == [10.0, 5.0, 3.0, 1.0, 1.0, 2.0, 1.0, 1.0, 2.0, 2.0]


def test_pbeam_stations_constant_to_five_digits_and_tapered():
    (beam,) = read_bdf_text("PBEAM,4,1,1.23456,2.,3.,,4.\n,\n,NO,1.,1.234561,2.000004\n")["PBEAM"]
    assert beam["STATIONS"] == ((0.0, 1.23456, 2.0, 3.0, 0.0, 4.0, 0.0), (1.0, 1.23456, 2.0, 3.0, 0.0, 4.0, 0.0))
    (taper,) = read_bdf_text("PBEAM,4,1,1.,2.,3.,,4.\n,\n,NO,.5,,,9.\n,NO,1.,3.\n,0.9\n")["PBEAM"]
    assert taper["STATIONS"] == ((0.0, 1.0, 2.0, 3.0, 0.0, 4.0, 0.0), (0.5, 2.0, 2.0, 9.0, 0.0, 4.0, 0.0),
                                 (1.0, 3.0, 2.0, 3.0, 0.0, 4.0, 0.0))
    assert (taper["A"], taper["K1"]) == (1.0, 0.9)
    (plain,) = read_bdf_text("PBEAM,4,1,1.,2.,3.\n")["PBEAM"]
    assert plain["STATIONS"] == ((0.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0), (1.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0))


def test_grdset_fills_only_blank_grid_fields():
    text = "GRID,1,,0.,0.,0.\nGRDSET,,3,,,,4,345,7\nGRID,2,0,1.,0.,0.,0,6,0\n"
    g1, g2 = read_bdf_text(text)["GRID"]
    assert [g1[k] for k in ("CP", "CD", "PS", "SEQID")] == [3, 4, 345, 7]
    assert [g2[k] for k in ("CP", "CD", "PS", "SEQID")] == [0, 0, 6, 0]
    (plain,) = read_bdf_text("GRID,1,,0.,0.,0.\n")["GRID"]
    assert [plain[k] for k in ("CP", "CD", "PS", "SEQID")] == [0, 0, None, None]


def test_scalar_points_on_mpc_and_springs_and_systems_now_accepted():
    bulk = read_bdf_text("MPC,1,100,,1.,2,3,-1.\nCELAS1,1,2,100,,5,3\nGRID,5,,0.,0.,0.,7\nCONM2,9,5,7,1.\n")
    assert bulk["MPC"][0]["TERMS"] == ((100, 0, 1.0), (2, 3, -1.0))
    assert (bulk["CELAS1"][0]["C1"], bulk["CELAS1"][0]["C2"]) == (0, 3)
    assert (bulk["GRID"][0]["CD"], bulk["CONM2"][0]["CID"]) == (7, 7)


def test_rigid_element_sharing_an_element_id_warns():
    text = "CBAR,10,1,1,2,0.,0.,1.\nRBE2,10,1,123456,3\n"
    with pytest.warns(UserWarning, match=re.escape("m.bdf:2: RBE2 10: element id 10 is also CBAR 10 at m.bdf:1")):
        bulk = read_bdf_text(text, name="m.bdf")
    assert (bulk["CBAR"][0].id, bulk["RBE2"][0].id) == (10, 10)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_bdf_text("CBAR,10,1,1,2,0.,0.,1.\nRBE2,11,1,123456,3\n")


def _raises(text: str, *parts: str) -> str:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        read_bdf_text(text, name="m.bdf")
    return str(info.value)


@pytest.mark.parametrize(
    "text, parts",
    [
        ("SPCADD,1\n", ("m.bdf:1: SPCADD 1 field 3 (S1): required field is blank",)),
        ("SPCADD,1,2,1\n", ("m.bdf:1: SPCADD 1 field 3 (S): set 1 lists itself",)),
        ("MPCADD,1,x\n", ("m.bdf:1: MPCADD 1 field 3 (S1): expected an integer",)),
        ("MPCADD,1,2\nMPCADD,1,3\n", ("m.bdf:2: MPCADD 1: duplicate MPCADD set id 1, already defined by MPCADD at m.bdf:1",)),
        ("GRDSET,1\n", ("m.bdf:1: GRDSET field 2: must be blank, got '1'",)),
        ("GRDSET,,-1\n", ("m.bdf:1: GRDSET field 3 (CP): coordinate system id must be >= 0, got -1",)),
        ("GRDSET,,1\nGRDSET,,2\n", ("m.bdf:2: GRDSET: only one GRDSET is allowed, another at m.bdf:1",)),
        ("SPOINT,5,THRU,2\n", ("m.bdf:1: SPOINT field 4 (ID): THRU range ends below its start (5 THRU 2)",)),
        ("SPOINT,THRU,2\n", ("m.bdf:1: SPOINT field 2 (THRU): THRU must follow a scalar point id",)),
        ("SPOINT\n", ("m.bdf:1: SPOINT field 2 (ID1): required field is blank",)),
        ("SPOINT,1,THRU,9\nGRID,5\n", ("m.bdf:2: GRID 5 field 2 (ID): grid 5 is also a scalar point (SPOINT at m.bdf:1)",)),
        ("CORD1R,1,2,2,3\n", ("m.bdf:1: CORD1R 1 field 3 (G1): the grids G1, G2, G3 must differ, got [2, 2, 3]",)),
        ("CORD1C,1,2,3\n", ("m.bdf:1: CORD1C 1 field 5 (G3): required field is blank",)),
        ("CORD1S,1,2,3,4,5\n", ("m.bdf:1: CORD1S 5 field 7 (G1): required field is blank",)),
        ("CORD2S,5,-1\n", ("m.bdf:1: CORD2S 5 field 3 (RID): reference system id must be >= 0",)),
        ("CORD2R,5\nCORD1C,5,1,2,3\n", ("m.bdf:2: CORD1C 5: duplicate coordinate system id 5, already defined by CORD2R",)),
        ("CONROD,1,1,2,3\n", ("m.bdf:1: CONROD 1 field 6 (A): required field is blank",)),
        ("CONM1,1,2,-1\n", ("m.bdf:1: CONM1 1 field 4 (CID): coordinate system id must be >= 0, got -1",)),
        ("CONM1,1,2,,1.\n,x\n", ("m.bdf:2: CONM1 1 field 2 (M33): expected a real number",)),
        ("CMASS2,1,,1,1\n", ("m.bdf:1: CMASS2 1 field 3 (M): required field is blank",)),
        ("CMASS1,1,1,1,9\n", ("m.bdf:1: CMASS1 1 field 5 (C1): component of point 1 must be 1..6 (a grid) or 0/blank",)),
        ("CDAMP1,1,1,,3\n", ("m.bdf:1: CDAMP1 1 field 5 (C1): component must be blank or 0 for a grounded end",)),
        ("CDAMP3,1,1\n", ("m.bdf:1: CDAMP3 1 field 4 (S1): both ends are grounded",)),
        ("CELAS4,1,1.,-3\n", ("m.bdf:1: CELAS4 1 field 4 (S1): scalar point id must be >= 0, got -3",)),
        ("CELAS3,1,1,1,2\nCMASS4,1,1.,1\n", ("m.bdf:2: CMASS4 1: duplicate element id 1, already defined by CELAS3",)),
        ("PMASS,1,1.,2\n", ("m.bdf:1: PMASS 2 field 5 (M): required field is blank",)),
        ("PDAMP,1,1.\nPMASS,1,2.\n", ("m.bdf:2: PMASS 1: duplicate property id 1, already defined by PDAMP",)),
        ("PVISC,1,1.,0.,7.\n", ("m.bdf:1: PVISC 1 field 5: must be blank, got '7.'",)),
        ("CVISC,1,1,2\n", ("m.bdf:1: CVISC 1 field 5 (G2): required field is blank",)),
        ("RBAR,1,1,2,123\n", ("m.bdf:1: RBAR 1 field 5 (CNA): CNA and CNB must hold six components in all, got 3",)),
        ("RBAR,1,1,2,123456,,1\n", ("m.bdf:1: RBAR 1 field 7 (CMA): component(s) 1 are in both CNA and CMA",)),
        ("RBAR,1,1,2,1234567\n", ("m.bdf:1: RBAR 1 field 5 (CNA): expected component digits",)),
        ("RROD,1,1,2,4\n", ("m.bdf:1: RROD 1 field 5 (CMA): expected a translation 1, 2 or 3, got 4",)),
        ("RROD,1,1,2,1,2\n", ("m.bdf:1: RROD 1 field 6 (CMB): only one of CMA and CMB may be given",)),
        ("RBE1,1,1,123456,2,123\n", ("RBE1 1 field 2 (UM): expected UM and the dependent grids", "got nothing")),
        ("RBE1,1\n", ("m.bdf:1: RBE1 1 field 3 (GN1): required field is blank",)),
        ("RBE1,1,1,123\n,UM,2,123\n", ("m.bdf:1: RBE1 1 field 4 (CN1): CN1, CN2, ... must hold six components",)),
        ("RBE1,1,1,123456\n,UM\n", ("RBE1 1", "(GM1): required field is blank (RBE1 needs dependent grids after UM)",)),
        ("RBE1,1,1,123456\n,UM,2\n", ("m.bdf:2: RBE1 1 field 4 (CM1): required field is blank",)),
        ("RBE2,5,1,123,2\nRBAR,5,1,2,123456\n",
         ("m.bdf:2: RBAR 5: duplicate rigid element id 5, already defined by RBE2 at m.bdf:1",)),
        ("SUPORT,1,7\n", ("m.bdf:1: SUPORT 1 field 3 (C): expected component digits",)),
        ("SUPORT1,1\n", ("m.bdf:1: SUPORT1 1 field 3 (ID): required field is blank",)),
        ("SUPORT1,1,2,3,4,5,6,1,8\n", ("m.bdf:1: SUPORT1 1 field 9: unexpected value",)),
        ("PBEAML,1,1,,BOX\n,1.,2.\n", ("m.bdf:2: PBEAML 1 field 4 (DIM3(A)): required field is blank",)),
        ("PBEAML,1,1,,ROD\n,1.,,MAYBE\n", ("m.bdf:2: PBEAML 1 field 4 (SO(1)): expected YES or NO, got 'MAYBE'",)),
        ("PBEAML,1,1,,ROD\n,1.,,NO,0.5,2.\n", ("m.bdf:2: PBEAML 1 field 5 (X/XB): the last station must be end B",)),
        ("PBEAML,1,1,,ROD\n,1.,,NO,1.5,2.\n", ("PBEAML 1 field 5 (X/XB): X/XB must lie in (0, 1], got 1.5",)),
        ("PBEAML,1,1,,ROD\n,1.,,NO,1.,2.,,NO,1.\n,3.\n", ("m.bdf:2: PBEAML 1 field 9 (X/XB): two stations at X/XB = 1.0",)),
        ("PBEAML,1,1,,WEIRD\n", ("m.bdf:1: PBEAML 1 field 5 (TYPE): section type 'WEIRD' is not in the MSC library",)),
        ("PBEAML,1,1,MYLIB,ROD\n,1.\n", ("m.bdf:1: PBEAML 1 field 4 (GROUP): section library 'MYLIB'",)),
        ("PBAR,1,1,1.\nPBEAML,1,1,,ROD\n,1.\n", ("m.bdf:2: PBEAML 1: duplicate property id 1, already defined by PBAR",)),
        ("PBEAM,1,1,1.\n,\n,NO,1.,x\n", ("m.bdf:3: PBEAM 1 field 4 (A): expected a real number",)),
        ("PBARL,3,1,,DBOX\n,10.,5.,3.,,1.\n", ("m.bdf:2: PBARL 3 field 5 (DIM4): required field is blank",)),
        ("DMIG,K,0,9,1,,,,3\n", ("m.bdf:1: DMIG K field 4 (IFO): rectangular matrices (IFO 9) are not supported",)),
        ("DMIG,K,0,3,1\n", ("m.bdf:1: DMIG K field 4 (IFO): expected 1 (square), 2 or 9 (rectangular), 6",)),
        ("DMIG,K,0,6,3\n", ("m.bdf:1: DMIG K field 5 (TIN): complex matrices (TIN 3) are not supported",)),
        ("DMIG,K,0,6,2\nDMIG,K,1,1,,1,1,1.,2.\n", ("m.bdf:2: DMIG K field 9 (B1): imaginary part of a real matrix",)),
        ("DMIG,K,1,1,,1,1,1.\n", ("m.bdf:1: DMIG K field 2 (NAME): column of matrix K without its header",)),
        ("DMIG,K,0,6,2\nDMIG,K,0,6,2\n", ("m.bdf:2: DMIG K field 2 (NAME): second header of matrix K, the first at m.bdf:1",)),
        ("DMIG,K,0,6,2\nDMIG,K,1,7,,1,1,1.\n", ("m.bdf:2: DMIG K field 4 (CJ): component must be 1..6 (a grid) or 0/b",)),
        ("DMIG,K,0,6,2\nDMIG,K,1,1,,2,1,1.\nDMIG,K,2,1,,1,1,1.\n",
         ("m.bdf:3: DMIG K field 6 (G1): term (1, 1) of column (2, 1) of K is given in both triangles",
          "(also at m.bdf:2)")),
        ("DMIG,K,0,1,2\nDMIG,K,1,1,,2,1,1.\n,2,1,3.\n", ("m.bdf:3: DMIG K field 2 (G2): term (2, 1) of column (1, 1)",
                                                          "given twice")),
        ("DMIG,K,0,6,2\nDMIG,K,1,1,,2,1\n", ("m.bdf:2: DMIG K field 8 (A1): required field is blank",)),
        ("EIGRL,1,10.,5.\n", ("m.bdf:1: EIGRL 1 field 4 (V2): V2 must exceed V1, got 10.0 and 5.0",)),
        ("EIGRL,1,,,0\n", ("m.bdf:1: EIGRL 1 field 5 (ND): number of roots must be > 0, got 0",)),
        ("EIGRL,1,,,5,,,,MIN\n", ("m.bdf:1: EIGRL 1 field 9 (NORM): expected MASS or MAX, got 'MIN'",)),
        ("EIGR,1,FOO\n", ("m.bdf:1: EIGR 1 field 3 (METHOD): expected one of LAN",)),
        ("EIGR,1,LAN,,,,,,,\n,POINT,1,2,x\n", ("m.bdf:2: EIGR 1 field 5: unexpected value",)),
        ("EIGRL,1\nEIGR,1\n", ("m.bdf:2: EIGR 1: duplicate eigenvalue method id 1, already defined by EIGRL at m.bdf:1",)),
        ("MPC,1,2,7,1.\n", ("m.bdf:1: MPC 1 field 4 (C1): component must be one of 1..6 (a grid) or 0/blank",)),
    ],
)
def test_malformed_new_cards(text, parts):
    _raises(text, *parts)
