"""3-D space frames as Nastran bulk data, for benchmarks and tests.

A tower of ``nz`` storeys on an ``nx × ny`` grid (1 m spacing, steel), clamped at the
base. Members are CBAR (PBAR with and without shear factors, and PBARL BOX) spread
over ``n_groups`` property ids so that correction factors on groups touch few
elements each. Every storey carries a floor mass (CONM2 with offset and inertia);
one sensor block hangs on an RBE2; one column has a flexible joint (CBUSH between
coincident grids) and the top has a grounded CELAS2 spring and a CROD brace.
"""

from __future__ import annotations


def frame_bdf(nx: int, ny: int, nz: int, n_groups: int = 20, coupmass: int = 1) -> str:
    """Free-field bulk data of the frame; about ``6·nx·ny·nz`` DoFs after the base SPC."""
    lines = ["$ jaxfem benchmark frame", f"PARAM,COUPMASS,{coupmass}",
             "MAT1,1,2.1+11,,0.3,7850.", "MAT1,2,7.0+10,2.6+10,,2700."]
    for g in range(n_groups):
        pid = 1 + g
        if g % 3 == 0:
            lines.append(f"PBAR,{pid},1,{2.0e-3 + 1e-5 * g:.6e},8.0e-6,5.0e-6,1.0e-5,0.0")
        elif g % 3 == 1:
            lines += [f"PBAR,{pid},1,{2.4e-3 + 1e-5 * g:.6e},6.0e-6,9.0e-6,1.2e-5,1.5",
                      "+,,,,,,,,", "+,0.833333,0.833333"]
        else:
            lines.append(f"PBARL,{pid},2,,BOX")
            lines.append(f",{0.08 + 0.001 * g:.4f},0.12,0.006,0.006")
    nid = lambda i, j, k: 1 + i + nx * (j + ny * k)
    for k in range(nz + 1):
        for j in range(ny):
            for i in range(nx):
                lines.append(f"GRID,{nid(i, j, k)},,{1.0 * i},{1.0 * j},{1.0 * k}")
    base = [nid(i, j, 0) for j in range(ny) for i in range(nx)]
    for start in range(0, len(base), 6):
        lines.append("SPC1,1,123456," + ",".join(str(b) for b in base[start:start + 6]))
    eid = 0
    members = []
    for k in range(nz + 1):
        for j in range(ny):
            for i in range(nx):
                if k < nz:
                    members.append((nid(i, j, k), nid(i, j, k + 1), "1.,0.,0."))
                if k > 0 and i + 1 < nx:
                    members.append((nid(i, j, k), nid(i + 1, j, k), "0.,0.,1."))
                if k > 0 and j + 1 < ny:
                    members.append((nid(i, j, k), nid(i, j + 1, k), "0.,0.,1."))
    top = nid(nx - 1, ny - 1, nz)
    joint = 900000  # a grid coincident with the top of the first column
    for ga, gb, v in members:
        eid += 1
        pid = 1 + (eid - 1) * n_groups // len(members)
        if ga == nid(0, 0, nz - 1) and gb == nid(0, 0, nz):
            gb = joint
        if eid % 7 == 0:  # some members with rigid end offsets
            lines.append(f"CBAR,{eid},{pid},{ga},{gb},{v}")
            lines.append(",,,0.,0.,0.01,0.,0.,-0.01")
        else:
            lines.append(f"CBAR,{eid},{pid},{ga},{gb},{v}")
    x0, y0, z0 = 0.0, 0.0, float(nz)
    lines.append(f"GRID,{joint},,{x0},{y0},{z0}")
    lines.append(f"CBUSH,{eid + 1},{n_groups + 1},{joint},{nid(0, 0, nz)},,,,0")
    lines.append(f"PBUSH,{n_groups + 1},K,1.e9,1.e9,1.e9,2.e6,2.e6,2.e6")
    lines.append(f"CELAS2,{eid + 2},5.0e5,{top},1")
    lines.append(f"CROD,{eid + 3},{n_groups + 2},{nid(0, 0, 1)},{nid(nx - 1, ny - 1, 1)}")
    lines.append(f"PROD,{n_groups + 2},1,1.0e-4,1.0e-8")
    sensor = 900001
    lines.append(f"GRID,{sensor},,{nx - 1 + 0.1},{ny - 1 + 0.1},{nz + 0.1}")
    lines.append(f"RBE2,{eid + 4},{top},123456,{sensor}")
    lines.append(f"CONM2,{eid + 5},{sensor},,0.5")
    for k in range(1, nz + 1):
        c = nid(nx // 2, ny // 2, k)
        lines.append(f"CONM2,{eid + 5 + k},{c},,{20.0 + k},0.05,0.0,0.1")
        lines.append(f",{1.0 + 0.01 * k},0.01,{1.2},0.0,0.0,{1.5}")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


SIZES = {"500": (3, 3, 10), "2000": (4, 4, 21), "5000": (5, 5, 34)}
