"""MuJoCo on OpenSim's laws: the forces a MuJoCo scene asks to follow OpenSim's laws rather
than MuJoCo's own (``laws.OpenSimLaws``): Simbody's Hunt-Crossley ground contact
(``hunt_crossley``), OpenSim's joint-limit springs (``limit_springs``) and Millard's muscle
forces (``muscles``), computed in Python and applied every MuJoCo step. This package file
imports nothing."""
