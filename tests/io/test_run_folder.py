"""A run folder is made of its own (``new_run_folder``) and, discarded, takes with it the folders
above it that it made and that nothing else uses now (``discard``)."""

from __future__ import annotations

from airl_cli.io.run_folder import discard, new_run_folder


def test_discard_removes_the_empty_folders_made_for_the_run_and_nothing_else(tmp_path):
    first = new_run_folder(str(tmp_path / "results" / "fit" / "a"), again=True)
    assert discard(first) and not (tmp_path / "results").exists()  # a refused first run leaves no results/fit/

    (tmp_path / "results").mkdir()  # the user's, made before: stays
    run = new_run_folder(str(tmp_path / "results" / "fit" / "b"), again=True)
    assert discard(run) and not (tmp_path / "results" / "fit").exists() and (tmp_path / "results").is_dir()

    kept = new_run_folder(str(tmp_path / "results" / "fit" / "c"), again=True)
    other = new_run_folder(str(tmp_path / "results" / "fit" / "d"), again=True)  # another run beside it
    assert discard(kept) and (tmp_path / "results" / "fit" / "d").is_dir()
    assert discard(other) and (tmp_path / "results").is_dir()  # results/fit/ was c's to remove, not d's: it stays, empty
