"""Analysis of sand piles and of ensembles of them (Moreau, section IV): never imports YADE.

Every module here reads snapshots (``.npz``, see :mod:`.snapshots`) and run records, and needs
numpy only (the figure modules also matplotlib), so it runs under any Python. A test enforces it
(``tests/analysis/test_layout.py``). SI units inside; figures say which unit they draw in.

The package's namespace holds the estimators (``from yadecd import analysis as pa``;
``pa.flank_slope(snap)``); the modules hold them by concern:

=================  ===========================================================================
:mod:`.snapshots`  reading snapshots; grain sets (pile, floor, slices, fossil layers, speeds);
                   meridian coordinates; grain-to-grain contacts
:mod:`.surface`    the free surface: profile, flank slope, bulk density
:mod:`.forces`     force densities on revolved cuts, reciprocal pairs, cylindrical cuts, the
                   fossil-layer law
:mod:`.ground`     the pressure on the floor and the central dip
:mod:`.fabric`     contact orientations, fabric tensor, force changes between solves
:mod:`.stats`      robust line fits, Student-t intervals, jackknife, first crossings
:mod:`.figures`    the figures (PNG) and the figure helpers every plotting module uses
:mod:`.report`     one pile's whole analysis: ``summary.json``, figures, the paper's table
:mod:`.ensemble`   ensembles of piles: records, means and intervals, their figures
:mod:`.protocols`  one protocol against another (Welch tests, paired branches)
=================  ===========================================================================
"""
from .snapshots import (REQUIRED_KEYS, SNAP_NAME, as_snapshot, load_snapshot, list_snapshots, run_parameters,
                        grain_masses, body_index, pile_mask, wall_only_grains, rest_speed, floor_level,
                        mean_diameter, slice_mask, fossil_layer, speed_levels, meridian, grain_contacts)
from .surface import (horizontal_pairs, surface_grains, flank_slope, profile_and_slope, FLANK_MIN_THICKNESS_D,
                      FLANK_CAP_RADIUS_D, FLANK_CAP_DROP_D, FLANK_MIN_SPAN_D, FLANK_MIN_POINTS, FLANK_CELL_ARC_D)
from .stats import (linear_fit, robust_line, t_quantile_975, t_cdf, mean_interval, jackknife_ratio_dip,
                    sweeps_to)
from .forces import (BandDensity, band_geometry, band_segment, band_force_density, reciprocal_pairs,
                     reciprocal_cuts, line_angles, cylindrical_cut_directions, layer_directions,
                     line_angle_between, fossil_law)
from .ground import ground_pressure, central_dip, wall_load, DIP_DISC_D, DIP_RING_D
from .fabric import contact_orientation_histogram, fabric_tensor, force_change

__all__ = [n for n in dir() if not n.startswith('_') and n not in (
    'snapshots', 'surface', 'stats', 'forces', 'ground', 'fabric')]
