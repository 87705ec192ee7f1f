"""What every part of the server stands on: the database models, the one error convention, Flask's extensions,
configuration, security, languages, the health checks, the OpenAPI document, URL converters, the import map and
gunicorn's settings."""
