"""jointid: joint-surface stiffness and damping identification by FE model updating.

Conventions (used throughout the package)
-----------------------------------------
* SI units inside the code: N, m, kg, s, Hz.  Column names and config keys carry the unit.
* Global axes: X lateral (across the rails), Y vertical (normal to the rail top), Z feed (along the rails).
* Mode shapes are arrays shaped ``(n_dofs_or_locations, n_modes)``, mass-normalised where they come
  from the FE model; frequencies in Hz; damping as ratios of critical.
* DOF numbering of the FE model is scikit-fem's for a vector ``ElementVector``: interleaved
  ``(ux, uy, uz)`` per node, i.e. dof = 3 * node + component.
"""

__version__ = "0.1.0"
