# Images of the rig, built from this repository (docker-compose.yml builds and names them):
#
#   docker build --target dev -t hil-rig-dev .    # the repository built the way a developer builds it
#                                                 # (tools/deps, make build): make test, make run
#   docker build --target runtime -t hil-rig .    # slim, for bring-up: hilrig installed from its
#                                                 # wheel, rerun, the Release firmware; no compilers,
#                                                 # qemu or chromium
#
# A plain `docker build .` builds the last stage, runtime.

# --- dev: everything, as on a developer's machine -------------------------------------------------
FROM debian:bookworm AS dev

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

# --- release: the Release firmware and the wheels, with only what building them takes -----------
FROM debian:bookworm AS release

ENV DEBIAN_FRONTEND=noninteractive \
    PYTHONDONTWRITEBYTECODE=1

# The firmware: g++, CMake, Ninja, CLI11 (no googletest: HIL_TESTS=OFF). The wheels: the CPython
# headers for hilrig's C extensions.
RUN apt-get update \
 && apt-get install -y --no-install-recommends g++ cmake ninja-build libcli11-dev python3-venv python3-dev \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /src
# The protocol generator (boardproto: canopen, cantools) and the wheel build (setuptools), at the
# versions requirements.lock pins; a layer of its own, rebuilt only when the lock changes.
COPY requirements.lock .
RUN python3 -m venv /opt/build-venv \
 && /opt/build-venv/bin/pip install --no-cache-dir --constraint requirements.lock setuptools canopen cantools

COPY . .
RUN cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DHIL_SANITIZE=OFF -DHIL_TESTS=OFF \
      -DHIL_PYTHON=/opt/build-venv/bin/python >/dev/null \
 && cmake --build build/release --target joint-firmware \
 && /opt/build-venv/bin/python tools/dist.py --out /dist

# --- runtime: hilrig, rerun and the firmware; nothing to build with ------------------------------
FROM debian:bookworm-slim AS runtime

ENV DEBIAN_FRONTEND=noninteractive \
    PYTHONDONTWRITEBYTECODE=1

# python3-venv: the venv hilrig lives in. libstdc++6: the Release firmware's one library beyond
# libc, libm and libgcc_s (ldd). iproute2: `ip link` for the CAN interfaces, `ip netns` for the
# private bus of `hilrig sim`.
RUN apt-get update \
 && apt-get install -y --no-install-recommends python3 python3-venv libstdc++6 iproute2 \
 && rm -rf /var/lib/apt/lists/*

WORKDIR /src
# The wheel (make dist), its dependencies at the versions requirements.lock pins (a constraint:
# only what hilrig needs is installed, rerun-sdk with its `rerun` CLI among them).
COPY requirements.lock /tmp/requirements.lock
COPY --from=release /dist/ /tmp/dist/
RUN python3 -m venv /src/.venv \
 && /src/.venv/bin/pip install --no-cache-dir --constraint /tmp/requirements.lock /tmp/dist/*.whl \
 && rm -rf /tmp/dist /tmp/requirements.lock

# hilrig's default firmware when installed: build/bin/joint-firmware under the working directory.
COPY --from=release /src/build/release/bin/joint-firmware /src/build/bin/joint-firmware

ENV PATH=/src/.venv/bin:$PATH
CMD ["hilrig", "--help"]
