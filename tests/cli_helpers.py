"""Test support for the command line's refusals: `rov-mav` in-process, the one stderr line it must give, what a
folder holds."""

from __future__ import annotations

from pathlib import Path

from rov_mav import cli


def files_under(folder: Path) -> set[Path]:
    return set(folder.rglob("*"))


def rov_mav(argv: list[str], capsys) -> tuple[int, str]:
    """(exit status, stderr) of `rov-mav ARGV` in-process: argparse's refusals raise SystemExit like the script."""
    try:
        status = cli.main(argv)
    except SystemExit as exc:
        status = exc.code
    return status, capsys.readouterr().err


def assert_one_line(err: str, *fragments: str) -> None:
    """Exactly one line on stderr, holding every fragment, and no trace of a traceback or an internal error."""
    assert err.endswith("\n") and err.count("\n") == 1, err
    for fragment in fragments:
        assert fragment in err, err
    assert "Traceback" not in err and "internal error" not in err, err
