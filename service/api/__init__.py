"""The REST API (FastAPI): jobs, their artifacts, scenes; bearer-token auth; errors as problem+json."""
