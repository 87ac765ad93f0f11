"""The ``jaxfem`` command line."""

from __future__ import annotations

import typer

from ._appropriate import appropriate
from ._check import check
from ._correlate import correlate
from ._demo import demo
from ._diagnose import diagnose
from ._frf import frf
from ._identify import identify
from ._modes import modes
from ._montecarlo import montecarlo
from ._update import update

# plain click errors: a rich error panel cuts long paths short ("File ... does not exist")
app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__, rich_markup_mode=None)


@app.callback()
def _main() -> None:
    """Differentiable structural dynamics: FE models, modes and model updating (SI units)."""
    import jax

    jax.config.update("jax_enable_x64", True)


for _command in (modes, check, demo, correlate, update, diagnose, frf, identify, appropriate, montecarlo):
    app.command()(_command)
