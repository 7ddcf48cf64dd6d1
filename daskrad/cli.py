"""The ``daskrad`` command line: argument parsing and error reporting, no logic
(docs/design.md §5)."""

from __future__ import annotations

import argparse
import contextlib
import gc
import signal
import sys
import threading
import warnings

from daskrad import __version__
from daskrad.errors import DaskradError, DaskradWarning, Terminated, interrupted


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit code 2 (docs/design.md §7)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"daskrad: error: {message} (see '{self.prog} --help')\n")
        sys.exit(2)


def _number(kind, text: str, what: str):
    """``kind(text)`` (int or float), or the one-line error naming ``what`` it must be."""
    try:
        return kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None


def _positive_int(text: str) -> int:
    value = _number(int, text, "a positive integer")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _nonneg_int(text: str) -> int:
    value = _number(int, text, "an integer >= 0")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = _number(float, text, "a positive finite number")
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def _fov(text: str) -> float:
    """A field of view in degrees, in (0, 180): the same words for 0 and for 200."""
    value = _number(float, text, "a number of degrees in (0, 180)")
    if not 0.0 < value < 180.0:
        raise argparse.ArgumentTypeError(f"must be a number of degrees in (0, 180), got {text}")
    return value


def _nonneg_float(text: str) -> float:
    value = _number(float, text, "a finite number >= 0")
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def _finite_float(text: str) -> float:
    value = _number(float, text, "a finite number")
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


_SCENE_HELP = "OBJ (with MTL), MGF, PLY, STL, glTF or GLB file, or a TOML of [[shape]]s"


def _vec3(text: str) -> tuple[float, float, float]:
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(abs(v) < float("inf") for v in values):
        raise argparse.ArgumentTypeError(f"must be three finite numbers X,Y,Z, got {text}")
    return values


def _default(name: str) -> str:
    """``(default X)`` from :class:`~daskrad.settings.Settings`, where every default lives."""
    from daskrad.settings import Settings

    return f"(default {getattr(Settings, name)})"


def _default_shots() -> str:
    """``--max-iterations``' default, which follows the scene's patch count."""
    from daskrad.settings import MIN_SHOTS, SHOTS_PER_PATCH

    return f"(default {SHOTS_PER_PATCH} a patch, at least {MIN_SHOTS})"


def _choices(registry: str) -> str:
    """The names of a registry, for ``--help`` only (the registries import numba kernels,
    which a plain run must not wait for before it has parsed its options)."""
    if registry == "methods":
        from daskrad.formfactor import METHODS as names
    else:
        from daskrad.direct import AREA_METHODS as names
    return ", ".join(sorted(names))


def build_parser(help_choices: bool = True) -> argparse.ArgumentParser:
    """The parser; ``help_choices`` lists the registries' names in the help (imports them)."""
    parser = _Parser(
        prog="daskrad",
        description="Progressive refinement radiosity with hemisphere-base form factors, on Dask.",
    )
    parser.add_argument("--version", action="version", version=f"daskrad {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True
    methods = f"one of: {_choices('methods')} " if help_choices else ""
    area_methods = f"one of: {_choices('area')} " if help_choices else ""

    info = commands.add_parser("info", help="load a scene and report its hierarchy and grid")
    info.add_argument("scene", help=_SCENE_HELP)
    info.add_argument("--config", help="TOML sidecar (default: SCENE with .toml suffix, if any)")
    info.add_argument("--camera", metavar="NAME", help="glTF: the camera to look through "
                                                       "(default: the file's first)")
    info.add_argument("--patch-size", type=_positive_float,
                      help="max patch edge, scene units (default: from the scene's size)")
    info.add_argument("--element-size", type=_positive_float,
                      help="max element edge (default: from the scene's size)")

    commands.add_parser("warmup", help="compile the numba kernels into their on-disk cache "
                                       "(make install does it; a run compiles them otherwise)")

    run = commands.add_parser("run", help="solve and render a scene")
    run.add_argument("scene", help=_SCENE_HELP)
    run.add_argument("-o", "--output", help="output image OUT.exr; OUT.png, OUT.json and the "
                                            "store OUT.zarr go beside it (default: SCENE stem "
                                            "+ .exr in the current directory)")
    run.add_argument("--config", help="TOML sidecar (default: SCENE with .toml suffix, if any)")
    run.add_argument("--camera", metavar="NAME", help="glTF: the camera to look through "
                                                      "(default: the file's first)")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_nonneg_int, metavar="N",
                       help="a local Dask cluster of N workers with its dashboard (threads of "
                            "this process unless --processes; default 0: no cluster, a thread "
                            "per core)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://HOST:PORT")
    run.add_argument("--processes", action="store_const", const=True,
                     help="--workers N as N worker processes reading the store, like the "
                          "machines of a real cluster (slower on one machine)")
    run.add_argument("--method", help=f"form-factor method, {methods}{_default('method')}")
    run.add_argument("--resolution", type=_positive_int,
                     help=f"item-buffer side R (hemicube: top face side) {_default('resolution')}")
    run.add_argument("--patch-size", type=_positive_float,
                     help="max patch edge, scene units (default: from the scene's size)")
    run.add_argument("--element-size", type=_positive_float,
                     help="max element edge (default: from the scene's size)")
    run.add_argument("--tolerance", type=_nonneg_float,
                     help=f"relative unshot RMS to stop at {_default('tolerance')}")
    run.add_argument("--max-iterations", type=_nonneg_int,
                     help=f"shots at most (0: direct light only, with the ambient term) "
                          f"{_default_shots()}")
    run.add_argument("--batch", type=_positive_int,
                     help=f"shooters per form-factor task (K) {_default('batch')}")
    run.add_argument("--sample-share", type=_nonneg_float,
                     help="share of the brightest patch's power (before the first shot) "
                          "below which a patch shoots from one point instead of its penumbra "
                          "samples (0: always sampled; 1 or more: all but the brightest "
                          "patches from one point) "
                          f"{_default('sample_share')}")
    run.add_argument("--relaxation", type=_positive_float, metavar="OMEGA",
                     help="overshooting, in [1, 2): a shot sends up to OMEGA times the "
                          "patch's unshot light (in proportion to what its receivers "
                          "reflect) and later shots take back the excess (1: plain "
                          f"progressive refinement) {_default('relaxation')}")
    run.add_argument("--spp", type=_positive_int, help=f"samples per pixel {_default('spp')}")
    run.add_argument("--edge-spp", type=_nonneg_int,
                     help="samples of a pixel whose --spp samples, with its neighbours', "
                          "differ (an edge), at most 1024; 0 or not more than --spp: none "
                          f"{_default('edge_spp')}")
    run.add_argument("--width", type=_positive_int, help="image width (default: the camera's)")
    run.add_argument("--height", type=_positive_int, help="image height (default: the camera's)")
    run.add_argument("--rdiff", type=_nonneg_float,
                     help="per-pixel pass threshold (eq. 9), in units of the scene's white "
                          f"level {_default('rdiff')}")
    run.add_argument("--no-per-pixel", dest="per_pixel", action="store_const", const=False,
                     help="no per-pixel pass: Gouraud-interpolated direct light only")
    run.add_argument("--subdivide", type=_nonneg_float,
                     help="relative spread of direct light splitting an element (0: off) "
                          f"{_default('subdivide')}")
    run.add_argument("--no-two-pass", dest="two_pass", action="store_const", const=False,
                     help="shoot area lights like any patch instead of gathering them")
    run.add_argument("--area-samples", type=_positive_int,
                     help=f"shadow rays per area light: N x N {_default('area_samples')}")
    run.add_argument("--area-method",
                     help=f"area-light shadows at vertices, {area_methods}(hemisphere: the "
                          "paper's window on the hemisphere base; rays: Lambert x shadow rays) "
                          f"{_default('area_method')}")
    run.add_argument("--mirror-depth", type=_nonneg_int,
                     help=f"mirror bounces per pixel ray {_default('mirror_depth')}")
    run.add_argument("--dashboard", metavar="HOST:PORT",
                     help=f"where a LocalCluster's dashboard listens {_default('dashboard')}")
    run.add_argument("--checkpoint-every", type=_positive_int,
                     help=f"batches between checkpoints into OUT.zarr (at least 5 s apart, the "
                          "first 5 s into the solve) "
                          f"{_default('checkpoint_every')}")
    run.add_argument("--resume", action="store_true",
                     help="continue from OUT.zarr's checkpoint; a smaller --tolerance or a "
                          "larger --max-iterations continues a finished store")
    run.add_argument("--exposure", type=_finite_float, metavar="STOPS",
                     help=f"PNG brightness in stops over the automatic exposure "
                          f"{_default('exposure')}")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")

    render = commands.add_parser(
        "render", help="a new image from a finished store: no direct pass, no solve")
    render.add_argument("store", help="OUT.zarr written by daskrad run")
    render.add_argument("-o", "--output", required=True,
                        help="the image VIEW.exr (VIEW.png beside it)")
    render.add_argument("--config", help="TOML whose [camera] replaces the run's camera")
    render.add_argument("--eye", type=_vec3, metavar="X,Y,Z",
                        help="camera position (default: the run's camera, or --config's)")
    render.add_argument("--look-at", type=_vec3, metavar="X,Y,Z",
                        help="point looked at (default: the run's)")
    render.add_argument("--up", type=_vec3, metavar="X,Y,Z", help="up direction (default: the "
                                                                    "run's)")
    render.add_argument("--fov", type=_fov,
                        help="horizontal field of view, degrees (default: the run's)")
    render.add_argument("--width", type=_positive_int, help="image width (default: the run's)")
    render.add_argument("--height", type=_positive_int,
                        help="image height (default: the run's)")
    render.add_argument("--spp", type=_positive_int, help="samples per pixel (default: the run's)")
    render.add_argument("--edge-spp", type=_nonneg_int,
                        help="samples of a pixel on an edge (default: the run's)")
    render.add_argument("--exposure", type=_finite_float, metavar="STOPS",
                        help="PNG brightness in stops over the automatic exposure (default 0)")
    render.add_argument("-q", "--quiet", action="store_true", help="no timing line")

    export = commands.add_parser(
        "export", help="the mesh with its baked vertex radiance (PLY, glTF binary, OBJ)")
    export.add_argument("store", help="OUT.zarr written by daskrad run")
    export.add_argument("output", help="OUT.ply, OUT.glb or OUT.obj")
    export.add_argument("--exposure", type=_finite_float, metavar="STOPS",
                        help="vertex colours' brightness in stops over the automatic exposure "
                             "(default 0; the linear radiance is written as it is)")
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None, *,
                  _default=warnings.showwarning):
    """A :class:`DaskradWarning` is one line, ``daskrad: warning: ...`` (no Python source
    line); any other warning is shown as Python shows it."""
    if issubclass(category, DaskradWarning):
        (file or sys.stderr).write(f"daskrad: warning: {message}\n")
    else:
        _default(message, category, filename, lineno, file, line)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(help_choices="-h" in argv or "--help" in argv).parse_args(argv)
    with warnings.catch_warnings():
        warnings.simplefilter("always", DaskradWarning)
        warnings.showwarning = _show_warning
        return _main(args)


def entry(argv: list[str] | None = None) -> int:
    """The ``daskrad`` command and ``python -m daskrad``: :func:`main`, and then the
    interpreter's last garbage collection skipped (:func:`gc.freeze`).

    When :func:`main` returns, every output is written and closed, the store and any cluster
    are closed and the threads left are idle; what the interpreter still does at exit is one
    full collection over every object the run made (numba's types and kernels, the mesh,
    Dask's state), only to free memory the system takes back at once. Frozen objects are left
    out of it: those reference counting frees as the modules are cleared are freed as before,
    those in reference cycles are never finalized (their ``__del__`` and weakref callbacks do
    not run; the system takes their memory). Nothing daskrad leaves at that point relies on
    one: files are closed in ``with`` blocks, executors and clusters are closed explicitly,
    and ``atexit`` handlers (``weakref.finalize`` with ``atexit=True``) run as before.
    Measured (the time from the end of ``main`` to the end of the process, less a bare
    interpreter's start): the Cornell box 0.15–0.19 → 0.03 s, with ``--workers 2``
    0.32–0.47 → 0.05 s (``bench_speed.exit_pair`` measures whole commands both ways). Not
    in :func:`main` itself, which tests call in one long process."""
    code = main(argv)
    gc.freeze()
    return code


def _terminate(signum, frame):
    # a SIGTERM sent to the whole group (a batch system's stop) ends the worker processes too,
    # and the scheduler in this process would log an ERROR for each key it can no longer
    # gather from them, before this process's one line: the run is stopping, Dask's account
    # of it is noise (Ctrl-C has none: the workers ignore SIGINT and the client closes them)
    import logging

    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    raise Terminated("terminated")


@contextlib.contextmanager
def _sigterm_stops_like_ctrl_c():
    """SIGTERM raises :class:`daskrad.errors.Terminated` in the block, as SIGINT raises
    KeyboardInterrupt: ``kill``, a batch system's stop or a container's shutdown then keep
    the last checkpoint, release the output's lock and say so in one line, where the default
    action killed the process silently and left ``.OUT.lock`` behind. Only from the main
    thread (signals reach it alone), and only over the default action: a handler the caller
    set stays."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return
    signal.signal(signal.SIGTERM, _terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _main(args) -> int:
    with _sigterm_stops_like_ctrl_c():
        return _command(args)


def _command(args) -> int:
    try:
        import numpy as np

        from daskrad import commands as subcommands

        # numbers beyond float64 are the user's to fix and each step checks its results are
        # finite (one line, exit 2): numpy's overflow warnings would only add noise before it
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if args.command == "info":
                print(subcommands.info_text(args))
            elif args.command == "run":
                subcommands.run_command(args)
            elif args.command == "warmup":
                subcommands.warmup_command()
            elif args.command == "render":
                subcommands.render_command(args)
            elif args.command == "export":
                subcommands.export_command(args)
    except DaskradError as err:
        sys.stderr.write(f"daskrad: error: {err.line()}\n")
        return 2
    except (OSError, MemoryError) as err:
        # disk full, a read-only or special file system, out of memory: the system's words,
        # on one line, naming the file
        where = f"{err.filename}: " if getattr(err, "filename", None) else ""
        what = getattr(err, "strerror", None) or str(err) or type(err).__name__
        sys.stderr.write(f"daskrad: error: {where}{what}\n")
        return 2
    except (KeyboardInterrupt, SystemError) as err:
        # Ctrl-C or SIGTERM inside a numba kernel surfaces as a SystemError chained to it
        stop = interrupted(err)          # the KeyboardInterrupt itself, or the one chained
        if stop is None:
            raise
        # a run says what it leaves (commands.resume_hint); elsewhere nothing is claimed
        why = getattr(stop, "message", None)
        terminated = isinstance(stop, Terminated) or getattr(stop, "terminated", False)
        word = "terminated" if terminated else "interrupted"
        sys.stderr.write(f"daskrad: {word}; {why}\n" if why else f"daskrad: {word}\n")
        return 143 if terminated else 130
    return 0


if __name__ == "__main__":
    sys.exit(entry())
