"""What an engineer looks at: plots, the self-contained HTML report, the 3-D shape view."""

from ._html import write_report as write_report
from ._montecarlo_plots import plot_montecarlo as plot_montecarlo
from ._plots import effect_where as effect_where
from ._plots import plot_convergence as plot_convergence
from ._plots import plot_damping as plot_damping
from ._plots import plot_effect_ranking as plot_effect_ranking
from ._plots import plot_freq_dev as plot_freq_dev
from ._plots import plot_frf_overlay as plot_frf_overlay
from ._plots import plot_mac as plot_mac
from ._shape_view import correlation_view as correlation_view
from ._shape_view import grid_translations as grid_translations
from ._shape_view import measured_geometry as measured_geometry
from ._shape_view import shape_view as shape_view
from ._structure_plots import plot_structure as plot_structure
from ._structure_plots import plot_surface as plot_surface
