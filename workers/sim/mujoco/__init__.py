"""The MuJoCo backend (``simulator.MujocoSimulator``): a neutral body built as an ``MjSpec``
(``build``, ``couplings``) or MyoSuite's MJCF (``mjcf_models``, ``mjcf_sources``), pruned
(``lock``, ``removal``, ``contacts``, ``moment_arms``) and compiled for a scene (``compile``),
posed (``pose``), drawn (``drawing``), its warnings logged
(``warning_log``); and the kinematic replay of a reference motion (``motion_replay``). This
package file imports nothing."""
