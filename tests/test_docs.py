"""The documentation site (mkdocs.yml, docs/) without building it: every page is in the navigation,
every command page names every option of its command, and every ``bash`` block of the README and
the pages names real things.

What the bash-block check does and does not do: it runs no command. For each line of a ``bash``
block not marked illustrative (the line ``<!-- illustrative -->`` just before its fence), every
command joined by ``&&`` must be one this project knows, and must name only what exists:

- ``airl ...``: the subcommand, each option (from the Typer app itself), and for the Hydra commands
  each override's config group, option and key, checked by the same functions ``airl`` runs before
  any work (``settings.command_line.checked``: ``check_group_choices``, ``check_keys``), so a misspelt key or group fails
  here as it would fail for a reader; for plot, report and inspect, at most as many arguments as
  the command takes;
- ``pip install``: the extras named exist in pyproject.toml; ``python[3] FILE.py``: the file exists;
- ``pytest``, ``mkdocs build|serve``, ``python3 -m venv``, ``. .venv/bin/activate``: known as they are.

Every ``airl generate|fit|sweep`` line is then dry-run (``_dry_run``): composed by Hydra and put
through the checks the command itself runs before any work, so a bad value, a missing environment
or a refused combination fails here. The README's 60-second tour runs end to end (a slow test).
Whether a long command then succeeds is for the tests of each command (and, for the tutorials, the
strict docs build that CI runs: ``mkdocs build --strict`` executes them).
"""

from __future__ import annotations

import ast
import re
import shlex
import tomllib
from pathlib import Path

import pytest
import typer
import typer.main
import yaml

from airl_cli.cli import app

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
ILLUSTRATIVE = "<!-- illustrative -->"
HYDRA_COMMANDS = {"generate": "airl", "fit": "airl", "sweep": "airl", "plan": "airl_plan"}


def _nav_paths(node) -> list[str]:
    """Every page path of a mkdocs ``nav`` (nested lists of paths and {title: path-or-list})."""
    if isinstance(node, str):
        return [node]
    if isinstance(node, list):
        return [p for item in node for p in _nav_paths(item)]
    if isinstance(node, dict):
        return [p for value in node.values() for p in _nav_paths(value)]
    return []


def _generated_pages() -> dict[str, str]:
    """The pages the hook adds from outside docs/ (site path -> repository path), read from its source."""
    source = (DOCS / "hooks" / "repo_pages.py").read_text()
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "PAGES" for t in node.targets):
            return {site: repo for repo, site in ast.literal_eval(node.value).items()}
    raise AssertionError("docs/hooks/repo_pages.py defines PAGES")


def test_every_page_is_in_the_nav_and_every_nav_entry_exists():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    nav = _nav_paths(config["nav"])
    assert len(nav) == len(set(nav)), "a page is in the nav twice"
    generated = _generated_pages()
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*") if p.suffix in (".md", ".ipynb") and "hooks" not in p.parts}
    assert not pages - set(nav), f"pages missing from the nav in mkdocs.yml: {sorted(pages - set(nav))}"
    missing = [p for p in nav if p not in pages and p not in generated]
    assert not missing, f"nav entries with no page: {missing}"
    assert all((ROOT / repo).is_file() for repo in generated.values())


def _commands() -> dict:
    """The subcommands of ``airl``, as the command line builds them (Typer's own click commands)."""
    return dict(typer.main.get_command(app).commands)


def _is_option(param) -> bool:
    return param.param_type_name == "option"


def _arguments(command) -> list:
    return [p for p in command.params if p.param_type_name == "argument"]


def _options(command) -> set[str]:
    """Every option name of a command (both spellings of a pair such as --plot/--no-plot), and --help."""
    names = {"--help"}
    for param in command.params:
        if _is_option(param):
            names.update(param.opts)
            names.update(param.secondary_opts)
    return names


def test_every_command_page_names_every_option_of_its_command():
    pages = {name: (DOCS / "commands" / f"{name}.md").read_text() for name in _commands()}
    for name, command in _commands().items():
        missing = [opt for opt in sorted(_options(command)) if f"`{opt}" not in pages[name]]
        missing += [p.name.upper() for p in _arguments(command) if f"`{p.name.upper()}`" not in pages[name]]
        assert not missing, f"docs/commands/{name}.md does not name {missing}"
    assert all(len(_options(c)) > 1 for c in _commands().values() if c.name != "plot" and c.name != "inspect")
    root = _options(typer.main.get_command(app))
    assert "--version" in root
    index = (DOCS / "commands" / "index.md").read_text()
    assert not [opt for opt in root if f"`{opt}" not in index], "docs/commands/index.md names the options of airl itself"


def test_every_setting_of_the_plan_group_and_of_each_method_has_its_row():
    from airl_cli.methods import REGISTRY

    plan_keys = yaml.safe_load((ROOT / "conf" / "plan" / "default.yaml").read_text())
    page = (DOCS / "commands" / "plan.md").read_text()
    assert not [k for k in plan_keys if f"`plan.{k}`" not in page]
    for name, method in REGISTRY.items():
        page = (DOCS / "methods" / f"{name.replace('_', '-')}.md").read_text()
        missing = [o.key for o in method.options if f"`method.{o.key}`" not in page]
        assert not missing, f"docs/methods/{name.replace('_', '-')}.md does not name method.{missing}"


def _bash_blocks() -> list[tuple[str, int, list[str]]]:
    """(file, line of the fence, the block's lines) of every ```bash block not marked illustrative."""
    blocks = []
    for path in [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]:
        lines = path.read_text().split("\n")
        i = 0
        while i < len(lines):
            if lines[i].strip() == "```bash":
                end = next(k for k in range(i + 1, len(lines)) if lines[k].strip().startswith("```"))
                marked = i > 0 and lines[i - 1].strip() == ILLUSTRATIVE
                if not marked:
                    blocks.append((path.relative_to(ROOT).as_posix(), i + 1, lines[i + 1 : end]))
                i = end
            i += 1
    return blocks


def _refused(check, *args) -> str | None:
    """The sentence a check refuses with (it prints it and exits 2, or raises ``ConfigError``), or None."""
    import contextlib
    import io

    from airl_cli.errors import ConfigError

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(err):
            check(*args)
    except ConfigError as refusal:
        return str(refusal)
    except (typer.Exit, SystemExit):
        return err.getvalue().strip() or "refused"
    return None


def _check_airl(words: list[str]) -> str | None:
    """Why an ``airl ...`` command names something that does not exist, or None."""
    from airl_cli.settings.command_line import checked

    commands = _commands()
    if not words or words[0].startswith("-"):
        unknown = [w for w in words if w not in _options(typer.main.get_command(app))]
        return f"not an option of airl: {unknown}" if unknown else None
    name, rest = words[0], words[1:]
    if name not in commands:
        return f"not a command: {name}"
    command = commands[name]
    takes_value = {opt for p in command.params if _is_option(p) and not p.is_flag for opt in p.opts}
    options, values, args = [], [], []
    i = 0
    while i < len(rest):
        word = rest[i]
        if word.startswith("-"):
            options.append(word)
            if word in takes_value:
                i += 1
        else:
            (values if name in HYDRA_COMMANDS else args).append(word)
        i += 1
    unknown = [o for o in options if o not in _options(command)]
    if unknown:
        return f"not an option of airl {name}: {unknown}"
    if name not in HYDRA_COMMANDS:
        arguments = _arguments(command)
        return f"airl {name} takes {len(arguments)} argument(s), given {args}" if len(args) > len(arguments) else None
    if [v for v in values if "=" not in v]:
        return f"not an override (GROUP=OPTION or KEY=VALUE): {[v for v in values if '=' not in v]}"
    return _refused(checked, name, values)  # a problem's own dynamics added (fit, generate), then the group choices and keys


def _check_command(words: list[str], extras: set[str]) -> str | None:
    """Why one command (no ``&&``) names something that does not exist, or None."""
    while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):  # environment variables first
        words = words[1:]
    if words[:1] == ["taskset"]:
        words = words[3:]
    if not words:
        return None
    program, rest = words[0], words[1:]
    if program == "airl":
        return _check_airl(rest)
    if program == "pip" and rest[:1] == ["install"]:
        named = [w for w in rest[1:] if not w.startswith("-")]
        bad = [w for w in named if not re.fullmatch(r"\.(\[[\w,]+\])?", w) or not set(re.findall(r"\w+", w)) <= extras]
        return f"pip install of something but this project or its extras {sorted(extras)}: {bad}" if bad else None
    if program in ("python", "python3"):
        if rest[:2] == ["-m", "venv"]:
            return None
        script = rest[0] if rest else ""
        return None if script.endswith(".py") and (ROOT / script).is_file() else f"no script {script!r} in the repository"
    if program in ("pytest", ".") or (program == "mkdocs" and rest[:1] in (["build"], ["serve"])):
        return None
    return f"unknown program {program!r}: mark the block {ILLUSTRATIVE} if it is not meant to be checked"


def test_every_bash_block_names_real_commands_options_and_settings():
    extras = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])
    blocks = _bash_blocks()
    assert len(blocks) >= 30, "the README and the pages have their bash blocks"
    problems = []
    for path, line, lines in blocks:
        installed: set[str] = set()  # the extras this block installs before its commands
        for k, text in enumerate(lines):
            words = shlex.split(text, comments=True)
            installed |= {e for w in words if w.startswith(".[") for e in re.findall(r"\w+", w)} if words[:2] == ["pip", "install"] else set()
            command: list[str] = []
            for word in [*words, "&&"]:
                if word != "&&":
                    command.append(word)
                    continue
                why = _check_command(command, extras)
                if why and any(f"airl's extra '{e}' installs" in why for e in installed):
                    why = None  # a launcher the block's own pip install line brings (hydra/launcher=ray after .[ray])
                if why:
                    problems.append(f"{path}:{line + 1 + k}: {text.strip()}\n    {why}")
                command = []
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("bad", ["airl fit mdp.nstates=5", "airl fitt", "airl sweep --partal experiment=fig05", "pip install .[nope]", "airl plot a b"])
def test_the_bash_check_catches_what_it_claims_to(bad):
    extras = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])
    assert _check_command(shlex.split(bad), extras)


#: Lines the dry run leaves to the static check above: a placeholder for the reader's own file or
#: package, a multirun or a printout (Hydra's own paths), a launcher whose extra is not installed.
_NOT_DRY_RUN = re.compile(r"<\w|mypackage|problem\.npz|(^| )-m( |$)|--cfg|--help|hydra/launcher=(ray|submitit)")


def _airl_lines() -> list[tuple[str, list[str]]]:
    """(where, words after ``airl``) of every ``airl generate|fit|sweep`` command of the checked bash blocks."""
    out = []
    for path, line, lines in _bash_blocks():
        for k, text in enumerate(lines):
            for part in " ".join(shlex.split(text, comments=True)).split(" && "):
                words = shlex.split(part)
                if words[:1] == ["airl"] and words[1:2] in (["generate"], ["fit"], ["sweep"]) and not _NOT_DRY_RUN.search(part):
                    out.append((f"{path}:{line + 1 + k}", words[1:]))
    return out


def _dry_run(command: str, rest: list[str]) -> str | None:
    """Why ``airl COMMAND REST`` would be refused before any work, or None: composed by Hydra and
    put through the checks the command runs first (``launch.preflight``: the settings, the memory,
    the dataset file; ``sweep.plan``: the sweep's jobs and its first job's settings)."""
    from airl_cli.errors import AirlError
    from airl_cli.jobs.launch import preflight
    from airl_cli.settings.problem_defaults import with_problem_defaults
    from airl_cli.sweep.plan import plan

    # the pages' run folders are new where their readers run them; here grid/ holds the fixture's file
    values = [w for w in rest if not w.startswith(("-", "hydra.run.dir="))]
    try:
        return _refused(plan, values) if command == "sweep" else _refused(preflight, command, with_problem_defaults(values))
    except AirlError as err:  # sweep.plan raises its sentence
        return str(err)


@pytest.fixture
def pages_files(tmp_path, monkeypatch):
    """A folder where the pages' ``mine.npz`` (demonstrated states and actions, as own-problem.md's
    is) and ``grid/dataset.npz`` exist."""
    from airl_cli import api

    monkeypatch.chdir(tmp_path)
    grid = api.make_dataset("mdp=grid", "dynamics=grid_suboptimal", "demos=exact", "seed=3")
    api.save_dataset(tmp_path / "mine.npz", api.make_dataset("mdp=grid", "dynamics=grid_suboptimal", "demos=sampled", "seed=3"))
    for folder in ("grid", "gen"):  # the pages' airl generate ... hydra.run.dir=FOLDER, then data=FOLDER/dataset.npz
        (tmp_path / folder).mkdir()
        api.save_dataset(tmp_path / folder / "dataset.npz", grid)
    return tmp_path


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_every_generate_fit_and_sweep_line_passes_its_dry_run(pages_files):
    """More than names: each ``airl generate|fit|sweep`` line of the pages passes ``_dry_run``. The
    jobs themselves do not run here (full sweeps take minutes); each command's own tests run them,
    and the tutorials run in the strict docs build."""
    from airl_cli.settings import compose_memo

    lines = _airl_lines()
    assert len(lines) >= 60, "the pages have their airl commands"
    with compose_memo.active():
        problems = [f"{where}: airl {' '.join(words)}\n    {why}" for where, words in lines if (why := _dry_run(words[0], words[1:]))]
    assert not problems, "\n".join(problems)
    assert not (pages_files / "results").exists(), "a dry run makes no folder"


@pytest.mark.parametrize("bad", ["fit mdp.discount=2", "fit data=nothere.npz", "sweep experiment=fig05 optim.lam=-1", "generate mdp.size=300 mdp=objectworld"])
def test_the_dry_run_refuses_what_the_command_would(pages_files, bad):
    words = bad.split()
    assert _dry_run(words[0], words[1:])


@pytest.mark.slow
def test_the_readmes_tour_runs_end_to_end(tmp_path):
    """The README's "60-second tour", line by line as a reader runs it, in a fresh folder (about a minute)."""
    import subprocess
    import sys

    text = (ROOT / "README.md").read_text()
    block = text.split("## A 60-second tour")[1].split("```bash")[1].split("```")[0]
    lines = [shlex.split(line, comments=True) for line in block.strip().splitlines()]
    assert len(lines) >= 5 and all(words[0] == "airl" for words in lines)
    for words in lines:
        done = subprocess.run([sys.executable, "-m", "airl_cli", *words[1:]], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{' '.join(words)}: {done.stderr}"
    assert (tmp_path / "fit" / "figures" / "convergence.png").is_file()
    assert (tmp_path / "results" / "sweeps" / "fig05-quick" / "figures").is_dir()


def test_no_list_runs_into_the_paragraph_before_it():
    """Python-Markdown (the site's) runs "- item" lines into a paragraph line just above them, where
    GitHub shows a list: every list in the pages starts after a blank line."""
    item = re.compile(r"^\s*(?:[-*+]|\d+\.)\s+\S")
    pages = [ROOT / "README.md", ROOT / "experiments" / "README.md", ROOT / "results" / "README.md", *sorted(DOCS.rglob("*.md"))]
    bad = []
    for path in pages:
        fenced, template, previous = False, False, ""
        for number, line in enumerate(path.read_text().split("\n"), 1):
            if line.startswith("<!-- numbers "):  # a passage's template: a comment the site never shows;
                template = True  # its rendering follows the line before the passage
                continue
            if template:
                template = line != "-->"
                continue
            if line == "<!-- /numbers -->":  # the passage's end: the site goes on from its last line
                continue
            if line.lstrip().startswith(("```", "~~~")):
                fenced = not fenced
            elif not fenced and item.match(line) and previous.strip() and not previous[:1].isspace():
                if not (item.match(previous) or previous.lstrip().startswith(("|", "#", ">"))):
                    bad.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:60]}")
            previous = "" if fenced else line
    assert not bad, "a blank line before these lists:\n" + "\n".join(bad)


def _python_blocks(page: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", (DOCS / page).read_text(), flags=re.M | re.S)


def test_the_dataset_file_example_writes_a_file_airl_reads(tmp_path, monkeypatch):
    """own-problem.md's np.savez example runs as written (its names once were defined nowhere)."""
    from airl_cli import api

    monkeypatch.chdir(tmp_path)
    block = next(b for b in _python_blocks("own-problem.md") if "np.savez" in b)
    exec(compile(block, "own-problem.md", "exec"), {})
    ds = api.load_dataset("mine.npz")
    assert (ds.n_dynamics, ds.n_states, ds.n_actions, ds.n_features, ds.horizon) == (2, 10, 4, 5, 8)


def test_the_finished_run_example_scores_the_new_dynamics(tmp_path, monkeypatch):
    """python-api.md's 'a finished run under new dynamics': its bash lines (made small), then its block."""
    from typer.testing import CliRunner

    monkeypatch.chdir(tmp_path)
    small = ["mdp.n_states=6", "mdp.n_actions=3", "mdp.horizon=5", "mdp.n_features=3", "demos.n=20"]
    assert CliRunner().invoke(app, ["generate", "hydra.run.dir=gen", *small]).exit_code == 0
    assert CliRunner().invoke(app, ["fit", "data=gen/dataset.npz", "hydra.run.dir=run", "pbvi.iterations=4"]).exit_code == 0
    block = next(b for b in _python_blocks("python-api.md") if "load_learned" in b and "with_test_dynamics" in b)
    *lines, last = block.strip().splitlines()
    scope: dict = {}
    exec(compile("\n".join(lines), "python-api.md", "exec"), scope)
    table = eval(last.split("#")[0], scope)
    assert list(table["dynamics"])[-2:] == ["test_1", "test_2"] and table["learner_score"].notna().all()


def test_the_typed_learners_example_fits_as_the_command_line_does(tmp_path, monkeypatch):
    """python-api.md's 'typed learners': its bash line, then its block (which asserts the weights
    of the command's fit and the typed learner's are equal, bit for bit), run as the page has them."""
    from typer.testing import CliRunner

    monkeypatch.chdir(tmp_path)
    assert CliRunner().invoke(app, ["fit", "method=mce", "hydra.run.dir=run-mce"]).exit_code == 0
    block = next(b for b in _python_blocks("python-api.md") if "api.Mce()" in b)
    scope: dict = {}
    exec(compile(block, "python-api.md", "exec"), scope)
    assert scope["airl"].info["converged"] and scope["airl"].method == "airl"
    assert scope["mmp"].info["iterations"] == 50


def test_the_planner_s_solvers_example_runs_as_written():
    """planner.md's 'solvers as objects': the block asserts the order mean <= PBVI <= optimum inside the bracket."""
    block = next(b for b in _python_blocks("planner.md") if "MultiModelProblem(" in b)
    scope: dict = {}
    exec(compile(block, "planner.md", "exec"), scope)
    from airl_cli.multimodel import Pbvi, solve

    assert scope["counted"].value >= solve(Pbvi(), scope["grid"]).value - 1e-9  # the optimum: no policy does better
