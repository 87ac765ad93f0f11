"""Error localisation: both indicators point at the property group that carries the error."""

import jax.numpy as jnp
import numpy as np

import jaxfem
from benchmarks.frames import frame_bdf
from identification import ModalData, Sensors, observation_matrix
from jaxfem.io import read_bdf_text
from updating import Options, Parameter, ParameterSet, build_problem, parameterise
from updating._localisation import group_scores, parameter_reduction, residual_forces


def test_both_indicators_find_the_erroneous_group():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(3, 3, 3, n_groups=6)))
    candidates = tuple(Parameter(f"pid{p}", "stiffness", pids=(p,)) for p in range(1, 7))
    base, par = parameterise(model, candidates)
    alpha = np.zeros(6)
    alpha[3] = -0.2  # the hidden error: property 4 is 20 % softer
    truth = par.apply(base, jnp.log1p(jnp.asarray(alpha)))
    lam, phi = jaxfem.eigh(*jaxfem.assemble(truth), 8)
    free = model.node_ids[(model.node_ids > 9) & (model.node_ids < 900000)]
    sensors = Sensors.from_components(np.repeat(free, 3), np.tile([1, 2, 3], len(free)))
    C, _ = observation_matrix(model, sensors)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(C @ phi), sensors)

    rho = parameter_reduction(build_problem(model, test, ParameterSet(candidates, Options())))
    assert int(np.argmax(rho)) == 3
    assert rho[3] > 0.5 and np.all(np.delete(rho, 3) < rho[3])

    scores = group_scores(residual_forces(model, np.asarray(lam), np.asarray(C @ phi), C)[0], model)
    assert next(iter(scores)) == 4  # highest residual-force energy in property 4
    assert all(v < 0.8 for p, v in scores.items() if p != 4)
