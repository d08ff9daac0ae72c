"""Time a cold start: launch to the first residual + tangent (Neo-Hookean + C2, 4³ cube).

The window of the target ends at the assembled tangent, as in ``bench compile``; the energy
kernel, compiled after it, is in the process totals printed beside it.

Run from the repository root with an empty cache for the cold case, again on the same cache for
the warm one::

    NUMBA_CACHE_DIR=$(mktemp -d) python -m benchmarks.cold_start

``--profile`` adds numba's compile time per function (self and inclusive seconds, and how often
each was compiled: a function compiled twice usually means a 2D and a 3D twin).
"""

import argparse
import collections
import resource
import time

START = time.time()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", action="store_true", help="compile time per function")
    arguments = parser.parse_args()
    own = collections.Counter()
    inclusive = collections.Counter()
    counts = collections.Counter()
    if arguments.profile:
        from numba.core import event

        stack = []

        class Listener(event.Listener):
            def on_start(self, record):
                function = getattr(record.data.get("dispatcher"), "py_func", None)
                name = f"{function.__module__}.{function.__qualname__}" if function else "?"
                stack.append([name, time.perf_counter(), 0.0])

            def on_end(self, record):
                if not stack:
                    return
                name, started, children = stack.pop()
                elapsed = time.perf_counter() - started
                inclusive[name] += elapsed
                own[name] += elapsed - children
                counts[name] += 1
                if stack:
                    stack[-1][2] += elapsed

        event.register("numba:compile", Listener())

    from benchmarks.compile import first_assembly

    phases, _ = first_assembly(4, launch_time=START)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    # The target's window ends at the first residual + tangent ("assembled"); the energy kernel
    # is compiled after it, so the process totals include it.
    print(
        f"first residual + tangent {phases['assembled']:.1f} s wall; process total "
        f"{time.time() - START:.1f} s wall, {usage.ru_utime + usage.ru_stime:.1f} s cpu"
    )
    for name, seconds in own.most_common(30):
        print(f"{seconds:6.2f} s self {inclusive[name]:6.2f} s inclusive x{counts[name]} {name}")


if __name__ == "__main__":
    main()
