# The NanoNav image: the API or a worker, chosen by the command (see docker-compose.yml).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /app
COPY pyproject.toml README.md alembic.ini ./
COPY nanonav ./nanonav
COPY service ./service
COPY worker ./worker
RUN pip install '.[postgres]' \
    && useradd --create-home nanonav \
    && chown -R nanonav /app
USER nanonav

EXPOSE 8000
CMD ["nanonav", "api", "--host", "0.0.0.0", "--port", "8000"]
