"""The HTTP client of the REST API and the CLI commands that use it (submit, jobs, status, logs, cancel, resume, download)."""
