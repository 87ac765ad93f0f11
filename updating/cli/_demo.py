"""``jaxfem demo``: the main job on an embedded case."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import load_model, load_test
from ._diagnose import diagnosis


def demo(
    out: Annotated[Path, typer.Option("--out", help="directory for the case, diagnosis.json and the report")] = Path("jaxfem-demo"),
) -> None:
    """The main job on an embedded case: the GARTEUR SM-AG19 model and modes "measured" on
    a truth with a hidden effect and noise. Diagnose, rank the candidate effects, add the
    winner, update again and write the report (a few minutes on 2 cores)."""
    import time

    from ..diagnosis import HIDDEN, PARAMETERS, demo_case

    start = time.perf_counter()
    typer.echo(f"simulating the measurement (hidden from the diagnosis: {HIDDEN}; fuselage stiffness +6 %; "
               "noise 0.2 % on frequencies, 1 % on shapes) ...", err=True)
    model_path, test_path = demo_case(out)
    typer.echo(f"case: {model_path} (nominal model), {test_path} (14 modes at 24 sensors); engineer's parameters: "
               + ", ".join(f"{p.name} ({p.kind} of pids {list(p.pids)})" for p in PARAMETERS.parameters))
    model = load_model(model_path)
    content: dict = {}
    test = load_test(test_path, None, content)
    diagnosis(model, test, PARAMETERS, model_name=model_path.name, test_name=test_path.name,
              json_out=out / "diagnosis.json", report=out / "report", test_content=content)
    typer.echo(f"demo done in {time.perf_counter() - start:.0f} s")
