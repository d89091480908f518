"""The HTTP front end of the job service: FastAPI app factory, routes and problem+json errors."""
