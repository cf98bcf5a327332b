"""Running a policy outside training, and what comes of it: evaluations of checkpoints
(``evaluate``: the episodes in ``episodes``, their statistics as observers in
``observers``, the results and their confidence intervals in ``results`` and ``stats``), a
stage judged on deterministic evaluations during training (``stage_judge``), MCAP recordings
(``recording``, ``recording_messages``, ``reference_pose``), MP4 videos (``video``,
``video_reference``), shipping a trained policy (``ship``), and the trainer's hooks that judge
stages and record checkpoints (``training_hooks``).

It may import the rest of ``gaitforge.learner`` (policies, checkpoints, curriculum, the hook
protocol) but not the trainer; of the rest of the learner, only the trainer imports it, and
only ``training_hooks`` (tests/test_import_graph.py). Importing this package imports none of
its modules.
"""
