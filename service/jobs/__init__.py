"""Jobs outside the web process: the on-disk layout of a job, its trainer process (the fixed
Ray job entrypoint) and the runner that queues, starts, follows and cancels them on Ray."""
