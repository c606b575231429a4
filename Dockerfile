# One image for every compose service (firmware, rig, viewer): the repository built the way a
# developer builds it, with the project's own installer (tools/deps) and `make build`.
#
#   docker build -t hil-rig .            # or: docker compose build
FROM debian:bookworm

ENV DEBIAN_FRONTEND=noninteractive \
    PYTHONDONTWRITEBYTECODE=1

# What tools/deps itself needs to run; it installs everything else (compilers, CMake,
# googletest, CLI11, iproute2, ...) and the pinned .venv from requirements.lock.
RUN apt-get update \
 && apt-get install -y --no-install-recommends make python3 ca-certificates \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /src
COPY . .
RUN tools/deps \
 && make build \
 && rm -rf /var/lib/apt/lists/*

ENV PATH=/src/.venv/bin:$PATH
CMD ["make", "help"]
