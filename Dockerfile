# millimpact in a container: Debian 12 with DOLFINx 0.5.2, PETSc/SLEPc 3.18 from Debian.
#   docker build -t millimpact .                  (or docker/build-image.sh: podman, builds and runs it)
#   docker run --rm -v $PWD/out:/out millimpact run --out /out/paper-rig
#   docker run --rm -v $PWD/out:/out --entrypoint mpirun millimpact -n 2 millimpact run --out /out/np2
#   docker run --rm -v $PWD/out:/out millimpact compare /out/ref/reference.h5 /out/dem.csv --out /out/cmp
# (docs/docker.md). Runs as root: the OMPI_* variables let mpirun start as root and put more ranks
# than cores; openssh-client comes with openmpi-bin (mpirun's launcher checks for it).
FROM debian:bookworm-slim
WORKDIR /opt/millimpact
COPY packages.txt dev pyproject.toml README.md ./
COPY millimpact ./millimpact
# build time only (not kept in the image): a CA bundle for pip behind a TLS-intercepting proxy
# (docker/build-image.sh mounts the host's and passes --build-arg PIP_CERT=/run/build-ca.crt)
ARG PIP_CERT
# The same packages.txt and install steps as the README's commands, slimmed in the same RUN (so
# nothing removed stays in a lower layer). Kept: the C compiler and the libc, gcc and Python headers
# and archives FFCx's JIT (cffi) compiles and links forms with at run time. Left out: documentation,
# manuals and translations (as Debian's -slim images do, whatever the base), the C++ Boost headers
# and MathJax that DOLFINx's -dev dependencies bring (nothing here compiles C++ or builds their docs),
# the other static archives, apt's lists, pip's cache, and the byte code of modules millimpact never
# imports (importing every millimpact module once compiles it again for all that they import).
RUN printf 'path-exclude %s\n' '/usr/share/doc/*' '/usr/share/man/*' '/usr/share/info/*' \
        '/usr/share/groff/*' '/usr/share/locale/*' '/usr/include/boost/*' '/usr/share/javascript/mathjax/*' \
        > /etc/dpkg/dpkg.cfg.d/millimpact-slim \
 && printf 'path-include %s\n' '/usr/share/doc/*/copyright' '/usr/share/locale/locale.alias' \
        >> /etc/dpkg/dpkg.cfg.d/millimpact-slim \
 && ./dev install \
 && dpkg -L libc6-dev > /tmp/keep \
 && find /usr/lib -name '*.a' ! -path '/usr/lib/gcc/*' | { grep -vxF -f /tmp/keep || true; } | xargs -r rm -f \
 && find / -xdev -name __pycache__ -type d -prune -exec rm -rf {} + \
 && MPLBACKEND=Agg .venv/bin/python -c "import importlib, pkgutil, millimpact, matplotlib.pyplot; \
        [importlib.import_module(m.name) for m in pkgutil.walk_packages(millimpact.__path__, 'millimpact.')]" \
 && rm -rf /var/lib/apt/lists/* /var/cache/apt/*.bin /var/cache/apt/archives/*.deb /root/.cache/pip /tmp/*
ENV PATH=/opt/millimpact/.venv/bin:$PATH \
    OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    MPLBACKEND=Agg
WORKDIR /out
ENTRYPOINT ["millimpact"]
CMD ["run", "--out", "/out/paper-rig"]
