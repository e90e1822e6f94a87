"""One package list: the README's commands (./dev), CI and the Dockerfile all install packages.txt."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _packages():
    return [l.split("#")[0].strip() for l in (ROOT / "packages.txt").read_text().splitlines()
            if l.split("#")[0].strip()]


def test_package_list_has_the_stack():
    pk = _packages()
    for name in ("python3-dolfinx", "python3-petsc4py", "python3-slepc4py", "python3-gmsh", "python3-meshio",
                 "python3-mpi4py", "python3-scipy", "python3-matplotlib", "python3-h5py", "python3-pytest",
                 "openmpi-bin"):
        assert name in pk


def test_dockerfile_installs_the_same_list_the_same_way():
    docker = (ROOT / "Dockerfile").read_text()
    assert docker.splitlines()[[l.startswith("FROM") for l in docker.splitlines()].index(True)].split()[1] \
        == "debian:bookworm-slim"
    assert "COPY packages.txt" in docker and "./dev install" in docker
    assert 'ENTRYPOINT ["millimpact"]' in docker and "OMPI_ALLOW_RUN_AS_ROOT=1" in docker
    dev = (ROOT / "dev").read_text()
    assert "packages.txt" in dev and "apt-get install" in dev
    assert "/usr/bin/python3 -m venv --system-site-packages" in dev


def test_readme_and_ci_use_the_dev_script():
    readme = (ROOT / "README.md").read_text()
    assert "./dev run" in readme and "./dev test" in readme
    assert "./dev test" in (ROOT / ".ci" / "run").read_text()
