"""Experimental-error Monte-Carlo studies (thesis §4.3): study files, the batched runner,
its chunk store, and Ray (also the plumbing a diagnosis' candidate fits use)."""

from ._montecarlo import ChunkStore as ChunkStore
from ._montecarlo import chunk_progress as chunk_progress
from ._montecarlo import duration as duration
from ._montecarlo import Runner as Runner
from ._montecarlo import montecarlo as montecarlo
from ._ray import montecarlo_ray as montecarlo_ray
from ._ray_pool import RayPool as RayPool
from ._ray_pool import pin_cpus as pin_cpus
from ._ray_pool import ray_cluster as ray_cluster
from ._ray_pool import to_device as to_device
from ._ray_pool import to_host as to_host
from ._study import CATEGORIES as CATEGORIES
from ._study import MonteCarloResult as MonteCarloResult
from ._study import Study as Study
from ._study import default_study as default_study
