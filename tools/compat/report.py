"""Collect the compat lanes' results into results.json and the versions table of the docs.

Usage: python3 report.py RESULTS_DIR RESULTS_JSON MARKDOWN LANE...

RESULTS_DIR holds what run.sh left per lane: ``<lane>.versions.json``, and per mode (serial,
mpi) ``<lane>-<mode>.status.json`` and the per-rank pytest counts ``<lane>-<mode>.counts.<rank>``.
MARKDOWN (docs/compatibility.md) is rewritten between the supported-versions markers only.
"""

from __future__ import annotations

import datetime
import json
import pathlib
import sys

BEGIN = "<!-- supported-versions:begin -->"
END = "<!-- supported-versions:end -->"
INSTALLED_FROM = {
    "host": "Debian bookworm `python3-dolfinx-real` (apt, the host)",
    "trixie": "Debian trixie `python3-dolfinx-real` (apt, in a debootstrap root)",
    "wheel": "PyPI wheel `dolfinx-solver-real` + `numba` (pip, venv on trixie's Python); "
    "this package installed from its built wheel, read-only",
}
MODES = {"serial": "serial", "mpi": "mpiexec -n 2"}
SHOWN = ("passed", "failed", "error", "skipped", "deselected")


def _mode_result(folder: pathlib.Path, lane: str, mode: str) -> dict:
    status_file = folder / f"{lane}-{mode}.status.json"
    if not status_file.exists():
        return {"ran": False}
    status = json.loads(status_file.read_text())
    ranks = {}
    for path in sorted(folder.glob(f"{lane}-{mode}.counts.*")):
        ranks[int(path.name.rsplit(".", 1)[1])] = json.loads(path.read_text())
    expected_ranks = 2 if mode == "mpi" else 1
    # Every rank runs the whole suite; a rank that wrote nothing died before pytest's summary.
    passed = status["exitstatus"] == 0 and len(ranks) == expected_ranks
    passed = passed and all(r["failed"] == 0 and r["error"] == 0 for r in ranks.values())
    return {
        "ran": True,
        "exitstatus": status["exitstatus"],
        "seconds": status["seconds"],
        "ranks": {str(rank): counts for rank, counts in ranks.items()},
        "result": "pass" if passed else "FAIL",
    }


def _counts_text(mode_result: dict) -> str:
    if not mode_result["ran"]:
        return "not run"
    ranks = list(mode_result["ranks"].values())
    if not ranks:
        return f"no pytest summary (exit status {mode_result['exitstatus']})"
    texts = {", ".join(f"{counts.get(key, 0)} {key}" for key in SHOWN) for counts in ranks}
    text = " / ".join(sorted(texts)) + (" per rank" if len(ranks) > 1 else "")
    return f"{text} ({mode_result['seconds']} s)"


def _skip_notes(lanes: list[dict]) -> list[str]:
    notes = []
    for lane in lanes:
        for mode, mode_result in lane["modes"].items():
            ranks = list(mode_result.get("ranks", {}).values())
            reasons = ranks[0].get("skip_reasons", {}) if ranks else {}
            for reason, count in sorted(reasons.items()):
                version = lane["versions"].get("dolfinx", lane["lane"])
                notes.append(f"- DOLFINx {version}, {MODES[mode]}: {count} skipped: {reason}")
    return notes


def _table(lanes: list[dict]) -> str:
    columns = ["DOLFINx", "Python, numba, NumPy", "installed from", "serial", "mpiexec -n 2"]
    columns += ["result", "date"]
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for lane in lanes:
        versions = lane["versions"]
        cells = [
            versions.get("dolfinx", "?"),
            f"{versions.get('python', '?')}, {versions.get('numba', '?')}, "
            f"{versions.get('numpy', '?')}",
            INSTALLED_FROM[lane["lane"]],
            _counts_text(lane["modes"]["serial"]),
            _counts_text(lane["modes"]["mpi"]),
            lane["result"],
            lane["date"],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    notes = _skip_notes(lanes)
    if notes:
        lines += ["", "Skipped tests (counted per rank under MPI):", "", *notes]
    return "\n".join(lines)


def main(folder: str, results_json: str, markdown: str, *lane_names: str) -> None:
    folder_path = pathlib.Path(folder)
    today = datetime.datetime.now(datetime.timezone.utc).date().isoformat()
    lanes = []
    for name in lane_names:
        versions_file = folder_path / f"{name}.versions.json"
        text = versions_file.read_text().strip() if versions_file.exists() else ""
        versions = json.loads(text) if text else {}
        modes = {mode: _mode_result(folder_path, name, mode) for mode in MODES}
        ok = all(m["ran"] and m["result"] == "pass" for m in modes.values())
        lanes.append(
            {
                "lane": name,
                "versions": versions,
                "modes": modes,
                "result": "pass" if ok else "FAIL",
                "date": today,
            }
        )
    # Lanes not run this time keep their last recorded result.
    path = pathlib.Path(results_json)
    previous = json.loads(path.read_text())["lanes"] if path.exists() else []
    ran = {lane["lane"] for lane in lanes}
    order = list(INSTALLED_FROM)
    merged = [lane for lane in previous if lane["lane"] not in ran] + lanes
    merged.sort(key=lambda lane: order.index(lane["lane"]))
    path.write_text(json.dumps({"lanes": merged}, indent=2) + "\n")

    markdown_path = pathlib.Path(markdown)
    text = markdown_path.read_text()
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    table = _table(merged)
    markdown_path.write_text(text[:start] + "\n" + table + "\n" + text[end:])
    for lane in lanes:
        print(f"{lane['lane']}: {lane['result']}")


if __name__ == "__main__":
    main(*sys.argv[1:])
