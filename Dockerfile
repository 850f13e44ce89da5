# syntax=docker/dockerfile:1
# The single `tessera` binary (render, serve, worker, submit, merge) on Debian 12, in two stages: a build stage with
# the compiler and -dev packages, and a slim runtime stage with only the shared libraries the binary links.
#
#   docker build -t tessera:0.1.0 .
#   docker run --rm tessera:0.1.0 render --help
#   docker run --rm -v "$PWD/scenes:/scenes:ro" -v "$PWD/out:/out" tessera:0.1.0 \
#       render /scenes/cbox_area_light.json -o /out/cbox.exr --spp 16
#   docker run -d -p 8470:8470 -v tessera-data:/var/lib/tessera -v /etc/tessera:/etc/tessera:ro tessera:0.1.0 \
#       serve --listen 0.0.0.0:8470 --data /var/lib/tessera \
#             --client-token-file /etc/tessera/client.token --worker-token-file /etc/tessera/worker.token
#
# tests/deploy/dockerfile.sh checks (without a Docker engine) that the runtime stage installs the Debian package of
# every shared library the built binary needs.

FROM debian:bookworm AS build
ARG DEBIAN_FRONTEND=noninteractive
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      build-essential cmake ninja-build pkg-config \
      libboost1.81-dev nlohmann-json3-dev libopenexr-dev libimath-dev libglm-dev libspdlog-dev libfmt-dev \
      libtinyobjloader-dev libtbb-dev libcli11-dev libsqlite3-dev libpng-dev zlib1g-dev libdeflate-dev libssl-dev \
 && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY . .
# Baseline x86-64 (no -march=native): the image runs on any x86-64 host. Tests and benchmarks are not built here;
# deploy/test.sh is the test command.
RUN cmake -S . -B /build -G Ninja -DCMAKE_BUILD_TYPE=Release -DTESSERA_WERROR=ON \
      -DTESSERA_BUILD_TESTS=OFF -DTESSERA_BUILD_BENCH=OFF \
 && cmake --build /build --target tessera -j"$(nproc)" \
 && install -D -m 0755 /build/cli/tessera /out/usr/bin/tessera

FROM debian:bookworm-slim AS runtime
ARG DEBIAN_FRONTEND=noninteractive
# One package per shared library of the binary (libc6 is in the base already, listed so the check stays exact;
# libsqlite3-0 for the coordinator's durable state), ca-certificates, and tini to pass signals on.
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libopenexr-3-1-30 libimath-3-1-29 libpng16-16 libtinyobjloader2rc10 libssl3 libtbb12 libspdlog1.10 libfmt9 \
      libstdc++6 libgcc-s1 libc6 zlib1g libdeflate0 libsqlite3-0 ca-certificates tini \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --uid 10001 --home-dir /var/lib/tessera --create-home --shell /usr/sbin/nologin tessera \
 && mkdir -p /var/cache/tessera && chown tessera:tessera /var/cache/tessera
COPY --from=build /out/ /
USER tessera
WORKDIR /var/lib/tessera
ENV XDG_CACHE_HOME=/var/cache
EXPOSE 8470
VOLUME ["/var/lib/tessera"]
# tini forwards SIGTERM to tessera (PID 1 would otherwise ignore it): `docker stop` lets a worker finish its tile
# (give it --stop-timeout longer than a tile) and lets the coordinator drain.
ENTRYPOINT ["/usr/bin/tini", "--", "/usr/bin/tessera"]
CMD ["--help"]
