# millimpact in a container: Debian 12 with DOLFINx 0.5.2, PETSc/SLEPc 3.18 from Debian.
#   docker build -t millimpact .
#   docker run --rm -v $PWD/out:/out millimpact run --out /out/paper-rig
#   docker run --rm -v $PWD/out:/out --entrypoint mpirun millimpact -n 2 millimpact run --out /out/np2
#   docker run --rm -v $PWD/out:/out millimpact compare /out/ref/reference.h5 /out/dem.csv --out /out/cmp
# (README.md, section Docker). Runs as root: the OMPI_* variables let mpirun start as root and put
# more ranks than cores; openssh-client comes with openmpi-bin (mpirun's launcher checks for it).
FROM debian:bookworm-slim
WORKDIR /opt/millimpact
COPY packages.txt dev pyproject.toml README.md ./
COPY millimpact ./millimpact
# build time only (not kept in the image): a CA bundle for pip behind a TLS-intercepting proxy
# (docker/build-image.sh mounts the host's and passes --build-arg PIP_CERT=/run/build-ca.crt)
ARG PIP_CERT
# the same packages.txt and the same install steps as the README's commands
RUN ./dev install && rm -rf /var/lib/apt/lists/*
ENV PATH=/opt/millimpact/.venv/bin:$PATH \
    OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    MPLBACKEND=Agg
WORKDIR /out
ENTRYPOINT ["millimpact"]
CMD ["run", "--out", "/out/paper-rig"]
