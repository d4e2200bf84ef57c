# syntax=docker/dockerfile:1
#
# geomint: build the release binary, then run it in a slim image as an unprivileged user.
#   docker build -t geomint .
#   docker run --rm -p 8080:8080 geomint
# Settings come from GEOMINT_* environment variables (see `geomint --help`). The default command
# lets anyone who reaches the port do everything, as on a single user's machine; a shared
# deployment mounts a tokens file and runs e.g. `serve --addr 0.0.0.0:8080 --tokens /data/tokens`
# (README, "Security").
#
# Where no image registry is reachable, every base is a build argument, and the binary and the
# page's libraries can come from the host instead of being built here:
#   --build-arg RUNTIME_BASE=IMAGE      the image the server runs in (default debian:bookworm-slim;
#                                       any Debian bookworm base, e.g. one made with debootstrap)
#   --build-arg NODE_BASE=IMAGE         the image that fetches the page's libraries with npm
#   --build-arg RUST_BASE=IMAGE         the image that compiles the binary
#   --build-arg BINARY=host --build-context host-binary=DIR
#                                       take DIR/geomint, the host's `cargo build --release`
#   --build-arg PAGE=host --build-context host-page=static
#                                       take the host's static/ with static/vendor/ from `npm ci`
# scripts/container-smoke builds the image that way from a debootstrapped base and checks it.
ARG RUNTIME_BASE=debian:bookworm-slim
ARG NODE_BASE=node:20-bookworm-slim
ARG RUST_BASE=rust:1-bookworm
ARG BINARY=built
ARG PAGE=built

FROM ${NODE_BASE} AS page-built
WORKDIR /src
COPY package.json package-lock.json ./
COPY scripts/vendor.mjs scripts/vendor.mjs
COPY static static
RUN npm ci --omit=dev --no-audit --no-fund

# ... or the host's static/, vendored by its own `npm ci`.
FROM ${RUNTIME_BASE} AS page-host
COPY --from=host-page . /src/static

FROM page-${PAGE} AS page

FROM ${RUST_BASE} AS binary-built
WORKDIR /src
COPY . .
# Cache mounts keep the registry and build artefacts between builds; the binary is copied out
# of the cached target directory.
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --release --locked --bin geomint \
    && install -D -m 0755 target/release/geomint /out/geomint

# ... or the host's release build.
FROM ${RUNTIME_BASE} AS binary-host
COPY --from=host-binary geomint /out/geomint

FROM binary-${BINARY} AS binary

FROM ${RUNTIME_BASE}
RUN useradd --system --uid 10001 --no-create-home --home-dir /nonexistent --shell /usr/sbin/nologin geomint \
    && mkdir -p /data/recordings /data/systems /data/jobs \
    && chown geomint /data/recordings /data/systems /data/jobs
COPY --from=binary /out/geomint /usr/local/bin/geomint
COPY --from=page /src/static /app/static
WORKDIR /app
ENV GEOMINT_ADDR=0.0.0.0:8080 \
    GEOMINT_STATIC_DIR=/app/static \
    GEOMINT_DATA_DIR=/data/recordings \
    GEOMINT_SYSTEMS_DIR=/data/systems \
    GEOMINT_JOBS_DIR=/data/jobs
# Stored Rerun recordings, system definitions and jobs (their parts and results); mount volumes
# here to keep them across containers.
VOLUME /data/recordings /data/systems /data/jobs
USER geomint
EXPOSE 8080
STOPSIGNAL SIGTERM
HEALTHCHECK --interval=30s --timeout=3s --start-period=5s \
    CMD ["bash", "-c", "exec 3<>/dev/tcp/127.0.0.1/8080 && printf 'GET /healthz HTTP/1.0\\r\\nHost: localhost\\r\\n\\r\\n' >&3 && head -n 1 <&3 | grep -q ' 200 '"]
ENTRYPOINT ["geomint"]
CMD ["serve", "--addr", "0.0.0.0:8080", "--anonymous", "all"]
