"""The OpenSim backend (``simulator.OpenSimSimulator``): a neutral body built as an
``opensim.Model``, pruned while built (``build``), stepped with a ``Manager`` per control
period (``manager``), measured (``size``) and drawn (``drawing``). Importing any of its
modules but this package file imports OpenSim."""
