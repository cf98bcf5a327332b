"""The learner (PPO, curriculum, policy blending, checkpoints). Not built yet: see the learner
issue; ``workers`` must never import this package."""
