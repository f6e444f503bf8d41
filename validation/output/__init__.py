"""What goes to files and screens: the plots of the studies (:mod:`.plots`), solve reports
and figure utilities (:mod:`.report`), the off-screen render of FEM fields (:mod:`.render`,
axisymmetric; :mod:`.render3d`, the 3D sector)."""
