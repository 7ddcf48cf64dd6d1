"""The ``daskrad`` command line: argument parsing and error reporting, no logic (DESIGN §5)."""

from __future__ import annotations

import argparse
import sys

from daskrad import __version__
from daskrad.errors import DaskradError


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit code 2 (DESIGN §7)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        sys.stderr.write(f"daskrad: error: {message} (see 'daskrad --help')\n")
        sys.exit(2)


def _positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _nonneg_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def _nonneg_float(text: str) -> float:
    value = float(text)
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def _area_method(text: str) -> str:
    # the names live with the methods (daskrad.direct); imported only when the option is given
    from daskrad.direct import AREA_METHODS

    if text not in AREA_METHODS:
        raise argparse.ArgumentTypeError(
            f"unknown area-light method {text!r} (choose from {', '.join(sorted(AREA_METHODS))})")
    return text


_SCENE_HELP = "OBJ (with MTL), MGF, PLY, STL, glTF or GLB file, or a TOML of [[shape]]s"


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="daskrad",
        description="Progressive refinement radiosity with hemisphere-base form factors, on Dask.",
    )
    parser.add_argument("--version", action="version", version=f"daskrad {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    commands.required = True

    info = commands.add_parser("info", help="load a scene and report its hierarchy and grid")
    info.add_argument("scene", help=_SCENE_HELP)
    info.add_argument("--config", help="TOML sidecar (default: SCENE with .toml suffix, if any)")
    info.add_argument("--patch-size", type=_positive_float, help="max patch edge, scene units")
    info.add_argument("--element-size", type=_positive_float, help="max element edge")

    run = commands.add_parser("run", help="solve and render a scene")
    run.add_argument("scene", help=_SCENE_HELP)
    run.add_argument("-o", "--output", help="output image OUT.exr (default: SCENE stem + .exr)")
    run.add_argument("--config", help="TOML sidecar (default: SCENE with .toml suffix, if any)")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_nonneg_int,
                       help="local worker processes (0: in-process; default: in-process below "
                            "~20k elements, else 2)")
    where.add_argument("--scheduler", help="address of an existing Dask scheduler, tcp://HOST:PORT")
    run.add_argument("--method", help="form-factor method (default: hemisphere)")
    run.add_argument("--resolution", type=_positive_int, help="item-buffer resolution R")
    run.add_argument("--patch-size", type=_positive_float, help="max patch edge, scene units")
    run.add_argument("--element-size", type=_positive_float, help="max element edge")
    run.add_argument("--tolerance", type=_positive_float, help="relative unshot RMS to stop at")
    run.add_argument("--max-iterations", type=_nonneg_int, help="shots at most")
    run.add_argument("--batch", type=_positive_int, help="shooters per form-factor task (K)")
    run.add_argument("--spp", type=_positive_int, help="samples per pixel")
    run.add_argument("--width", type=_positive_int, help="image width (default: the camera's)")
    run.add_argument("--height", type=_positive_int, help="image height")
    run.add_argument("--rdiff", type=_nonneg_float,
                     help="per-pixel pass threshold (eq. 9), in units of the scene's white "
                          "level (default 0.1)")
    run.add_argument("--no-per-pixel", dest="per_pixel", action="store_const", const=False,
                     help="no per-pixel pass: Gouraud-interpolated direct light only")
    run.add_argument("--subdivide", type=_nonneg_float,
                     help="relative spread of direct light splitting an element (0: off)")
    run.add_argument("--no-two-pass", dest="two_pass", action="store_const", const=False,
                     help="shoot area lights like any patch instead of gathering them")
    run.add_argument("--area-samples", type=_positive_int,
                     help="shadow rays per area light: N x N (default 4)")
    run.add_argument("--area-method", type=_area_method,
                     help="area-light shadows at vertices: hemisphere (the paper's window on "
                          "the hemisphere base; default) or rays (Lambert x shadow rays)")
    run.add_argument("--mirror-depth", type=_nonneg_int, help="mirror bounces per pixel ray")
    run.add_argument("--dashboard", metavar="HOST:PORT",
                     help="where a LocalCluster's dashboard listens (default 127.0.0.1:8787)")
    run.add_argument("--checkpoint-every", type=_positive_int,
                     help="batches between checkpoints into OUT.zarr (default 8)")
    run.add_argument("--resume", action="store_true", help="continue from OUT.zarr's checkpoint")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        from daskrad import run as pipeline

        if args.command == "info":
            print(pipeline.info_text(args))
        elif args.command == "run":
            pipeline.run_cli(args)
    except DaskradError as err:
        sys.stderr.write(f"daskrad: error: {err.line()}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("daskrad: interrupted; the last checkpoint is kept (use --resume)\n")
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
