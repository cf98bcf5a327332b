"""The REST API (FastAPI): jobs, their artifacts, scenes; bearer-token auth; errors as problem+json.

app = create_app(ServiceSettings())      # lifespan: store, Ray, runner
uvicorn.run(app, host=settings.host, port=settings.port)
"""

from gaitforge.service.api.app import create_app

__all__ = ["create_app"]
