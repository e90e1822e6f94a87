"""``millimpact table`` input as ``study`` takes it (issue 35, row 11): a repeated value is refused
(a duplicate row would weight the fitted laws), an option nothing reads is warned about."""
import pytest

from conftest import run_cli


@pytest.mark.parametrize("args,said", [
    (["--velocity", "1,1"], "--velocity '1,1': 1 is repeated"),
    (["--velocity", "1,2", "--angle", "0,30,30.0"], "--angle '0,30,30.0': 30 is repeated"),
    (["--velocity", "1", "--radius", "0.01,0.02,0.01"], "--radius '0.01,0.02,0.01': 0.01 is repeated"),
])
def test_repeated_values_are_refused(args, said, tmp_path):
    out = tmp_path / "t"
    r = run_cli("table", "hertz-halfspace", "--method", "hertz", *args, "--out", str(out))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and said in lines[0], r.stderr
    assert not out.exists()


def test_an_option_nothing_reads_is_warned_about(tmp_path):
    out = tmp_path / "t"
    r = run_cli("table", "hertz-halfspace", "--method", "hertz", "--velocity", "1,2", "--option", "nosuch=3",
                "-q", "--out", str(out))
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if "warning: options that nothing" in line]
    assert len(warnings) == 1 and warnings[0].endswith(": -nosuch")     # once, not once a case
    assert (out / "contact_table.csv").is_file()
