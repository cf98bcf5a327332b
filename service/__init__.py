"""The gaitforge service: REST API, job store, job runner and the ``gaitforge`` CLI."""
