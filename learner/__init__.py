"""The learner: PPO pieces so far (GAE, running normaliser, Gaussian actor-critic, PPO
update). The trainer loop, curriculum, policy blending, checkpoints, evaluation and
recordings are the learner issue's remaining work. ``workers`` never imports this package.
"""
