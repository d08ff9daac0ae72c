"""Run every scene of the gallery, render one picture each with ParaView, write the table.

Usage (``make gallery`` runs it): ``.venv/bin/python tools/gallery.py [SCENE ...]``

For each entry of :data:`GALLERY` it runs the exact command the README shows (a child process,
so the measured wall time is what a user sees, start-up included), renders
``docs/gallery/<name>.png`` from the run's own XDMF at a telling time with the scene's obstacles
(:mod:`dolfinx_invertible.scenes.pictures`), animates the first entry of every dynamic scene
into ``docs/gallery/<name>.gif``, and records the command, the wall time, the cells and the
outcome in ``docs/gallery/gallery.json``; the README's gallery table (between its markers) is
rewritten from that file. Entries not run keep their last record.

Resolutions: at least 5 000 cells where the run then takes under two minutes on this project's
2-core machine. Measured over two minutes (Intel Xeon, 2026-12-04), so kept at their defaults:
the compress block at 5 184 cells (241 s), the scatter at 6 000 (2 ranks), the corotated
stretch bar at 6 480 and the tight tube at 5 184 (each stopped at 125–150 s). The
one-tetrahedron, three-triangle and 2D scenes are small by design. One entry is large on
purpose: the collapse at resolution 32 (196 608 cells, 107 811 unknowns), on the iterative path
that every mesh above the direct limit takes, the size whose first step the trust region took
89–132 Newton iterations for, through an inverted minimum, before Newton's local phase kept the
exact direction past negative curvature (6 now).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parents[1]
GALLERY_DIRECTORY = REPOSITORY / "docs" / "gallery"
README = REPOSITORY / "README.md"
BEGIN, END = "<!-- gallery:begin -->", "<!-- gallery:end -->"

# name, scene, arguments, ranks, the time to show, what the picture shows
GALLERY = [
    ("collapse", "collapse", ["--resolution", "10"], 2, 0.04,
     "cube collapsed to a point springing back (t = 0.04 s)"),
    ("collapse-large", "collapse", ["--resolution", "32"], 2, 0.01,
     "the same collapse at 2·10⁵ cells after its first step (t = 0.01 s): out of the collapse "
     "in 6 Newton iterations, no cell inverted on the way (the iterative path, CG + GAMG)"),
    ("scatter", "scatter", [], 2, "first", "scattered vertices, half the cells inverted at t = 0"),
    ("scatter-end", "scatter", [], 2, "last", "the same cube back at rest"),
    ("stretch-bar-corotated", "stretch-bar", ["--model", "corotated"], 1, "most-inverted",
     "corotated bar at 4× stretch: inverted cells along the bar"),
    ("stretch-bar", "stretch-bar", ["--resolution", "6"], 1, "last",
     "Neo-Hookean + C2 at 4× stretch: no inversion"),
    ("tet-stretch-corotated", "tet-stretch", ["--model", "corotated"], 1, "last",
     "one corotated tetrahedron driven onto the energy kink"),
    ("mattress-2d-corotated", "mattress-2d", ["--model", "corotated", "--nu", "0.45"], 1, "last",
     "corotated mattress at 3× stretch: inverted elements"),
    ("triangles-2d-corotated", "triangles-2d", ["--model", "corotated"], 1, 0.02,
     "three corotated triangles relaxing; the stretched one passes through inversion"),
    ("cook-membrane", "cook-membrane", [], 1, "last", "Cook's membrane, P2, ν = 0.4999"),
    ("twisting-column", "twisting-column", ["--scheme", "bdf2", "--resolution", "6"], 1, "last",
     "twisting column at t = 0.3 s (BDF2)"),
    ("compress-block", "compress-block", [], 1, "most-inverted",
     "block under the plate: inverted cells held by the extension"),
    ("compress-block-end", "compress-block", [], 1, "last", "the block recovered after release"),
    ("square-inv-free", "square-inv-free", [], 1, "most-inverted",
     "plain Neo-Hookean squashed with inversion-free steps"),
    ("bowl-drop", "bowl-drop", ["--resolution", "10"], 2, "last",
     "a cube dropped into a bowl, at rest at the bottom"),
    ("ball-hit", "ball-hit", ["--resolution", "10"], 2, "most-inverted",
     "a block struck by a ball: cells inverted"),
    ("tight-tube", "tight-tube", [], 1, "most-inverted",
     "a body pushed through a narrowing tube, squeezed at the throat"),
    ("gap-squeeze", "gap-squeeze", ["--resolution", "10"], 2, "most-inverted",
     "a body squeezed between two cylinders"),
    ("gap-squeeze-friction", "gap-squeeze", ["--friction", "0.5"], 1, "most-inverted",
     "the turning rollers grip the body (μ = 0.5) and pull it through"),
    ("cubes-in-bowl", "cubes-in-bowl", [], 2, "last",
     "8 soft cubes piled in the bowl, cube on cube through IPC Toolkit"),
    ("links", "links", [], 1, 0.15, "a chain of rings caught on each other, stretched"),
]  # fmt: skip


def _command(scene: str, arguments: list[str], ranks: int, output: Path) -> list[str]:
    command = [sys.executable, "-m", "dolfinx_invertible", "run", scene, *arguments, "--quiet",
               "--out", str(output)]  # fmt: skip
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    return command


def _shown_command(scene: str, arguments: list[str], ranks: int) -> str:
    command = " ".join(["dolfinx-invertible", "run", scene, *map(shlex.quote, arguments)])
    return f"mpirun -n {ranks} {command}" if ranks > 1 else command


def run_entry(entry) -> dict:
    """Run one gallery entry, render its picture (and animation); return its record."""
    from dolfinx_invertible.scenes import get_scene
    from dolfinx_invertible.scenes.pictures import animate_run, render_run

    name, scene, arguments, ranks, shown_time, caption = entry
    output = REPOSITORY / "results" / "gallery" / name
    environment = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    start = time.perf_counter()
    completed = subprocess.run(
        _command(scene, arguments, ranks, output), env=environment, capture_output=True,
        text=True, timeout=3600,
    )  # fmt: skip
    wall = time.perf_counter() - start
    summary = json.loads((output / "summary.json").read_text())
    if completed.returncode not in (0, 1):
        raise RuntimeError(f"{name}: {completed.stderr[-2000:]}")
    picture = GALLERY_DIRECTORY / f"{name}.png"
    render_run(output, picture, time=shown_time, title=name)
    animation = None
    first_of_scene = next(e for e in GALLERY if e[1] == scene)[0] == name
    if get_scene(scene).dynamic and first_of_scene:
        animation = GALLERY_DIRECTORY / f"{name}.gif"
        animate_run(output, animation, title=name)
    result = summary["outcome"]
    for key in (
        "max_inverted",
        "rest_distance",
        "tip_displacement",
        "energy_loss",
        "cross_section_ratio",
        "oscillation_amplitude",
        "min_gap",
        "penetrations",
        "min_distance",
        "intersections",
    ):
        if key in summary and summary[key] is not None:
            value = summary[key]
            result += f", {key} {value:.3g}" if isinstance(value, float) else f", {key} {value}"
    return {
        "name": name,
        "scene": scene,
        "command": _shown_command(scene, arguments, ranks),
        "caption": caption,
        "wall_time_s": round(wall, 1),
        "result": result,
        "cells": json.loads((output / f"{scene}.jsonl").read_text().splitlines()[0])["cells"],
        "picture": f"docs/gallery/{name}.png",
        "animation": None if animation is None else f"docs/gallery/{name}.gif",
    }


def table(records: list[dict]) -> str:
    """Return the README's gallery table."""
    from dolfinx_invertible.scenes import get_scene

    lines = ["| picture | scene (paper) | what it shows | command | cells | wall time | result |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for record in records:
        figure = get_scene(record["scene"]).figure
        animation = record.get("animation")
        moving = f"<br>[animation]({animation})" if animation else ""
        lines.append(
            f"| ![{record['name']}]({record['picture']}){moving} | `{record['scene']}` "
            f"({figure}) | {record['caption']} | `{record['command']}` | "
            f"{record.get('cells') or '—'} | {record['wall_time_s']} s | {record['result']} |"
        )
    return "\n".join(lines)


def main(names: list[str]) -> int:
    """Run the named entries (all by default); rewrite gallery.json and the README table."""
    GALLERY_DIRECTORY.mkdir(parents=True, exist_ok=True)
    store = GALLERY_DIRECTORY / "gallery.json"
    records = {r["name"]: r for r in json.loads(store.read_text())} if store.exists() else {}
    for entry in GALLERY:
        if names and entry[0] not in names:
            continue
        print(f"gallery: {entry[0]} ...", flush=True)
        records[entry[0]] = run_entry(entry)
        print(f"gallery: {entry[0]}: {records[entry[0]]['result']} "
              f"({records[entry[0]]['wall_time_s']} s)", flush=True)  # fmt: skip
        # After every entry: an interrupted gallery keeps the records of its new pictures.
        _write(records, store)
    _write(records, store)
    return 0


def _write(records: dict, store: Path) -> None:
    ordered = [records[e[0]] for e in GALLERY if e[0] in records]
    ordered += [r for name, r in records.items() if name not in {e[0] for e in GALLERY}]
    store.write_text(json.dumps(ordered, indent=2) + "\n")
    text = README.read_text()
    if BEGIN in text and END in text:
        start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
        README.write_text(text[:start] + "\n" + table(ordered) + "\n" + text[end:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
