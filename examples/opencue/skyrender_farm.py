#!/usr/bin/env python3
"""Submit skyrender work to an OpenCue farm with PyOutline.

Two jobs, using only the `skyrender` command line:

  tiles     one image as N tiles (a layer whose frames 0..N-1 are the
            tile indices) and a merge layer that waits for all of them;
  timelapse one frame of a day per OpenCue frame.

OpenCue substitutes #IFRAME# in a Shell layer's command with the frame
number. The output directory must be on storage every render host sees.

  python3 skyrender_farm.py tiles --tiles 16 --out /shared/sky \
      -- --preset sunset --width 4096 --height 2048 --spp 64
  python3 skyrender_farm.py timelapse --start 2013-05-27T04:00:00-04:00 \
      --end 2013-05-27T22:00:00-04:00 --frames 217 --out /shared/day \
      -- --lat 42.4434 --lon -76.4816 --width 1024 --height 512 --spp 32

Not run in this repository's CI (no OpenCue deployment there); the same
work on Slurm is tested end to end (examples/slurm/, tests/slurm.rs).
"""

import argparse
import getpass

from outline import Outline, cuerun
from outline.modules.shell import Shell


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=["tiles", "timelapse"])
    parser.add_argument("--skyrender", default="skyrender")
    parser.add_argument("--out", required=True)
    parser.add_argument("--tiles", type=int, default=4)
    parser.add_argument("--start")
    parser.add_argument("--end")
    parser.add_argument("--frames", type=int)
    parser.add_argument("--show", default="testing")
    parser.add_argument("--shot", default="sky")
    parser.add_argument("scene", nargs=argparse.REMAINDER)
    args = parser.parse_args()
    scene = [a for a in args.scene if a != "--"]
    render = [args.skyrender, "render", *scene]

    job = Outline(f"skyrender-{args.kind}", show=args.show, shot=args.shot,
                  user=getpass.getuser())
    if args.kind == "tiles":
        tiles = Shell("tiles", range=f"0-{args.tiles - 1}", command=render + [
            "--tiles", str(args.tiles), "--tile-index", "#IFRAME#", "--resume",
            "-o", f"{args.out}/part_#IFRAME#.exr"])
        merge = Shell("merge", range="1", command=[
            "sh", "-c", f'"{args.skyrender}" merge "{args.out}"/part_*.exr -o "{args.out}/sky.exr"'])
        merge.depend_all(tiles)
        job.add_layer(tiles)
        job.add_layer(merge)
    else:
        job.add_layer(Shell("frames", range=f"1-{args.frames}", command=render + [
            "--time-start", args.start, "--time-end", args.end,
            "--frames", str(args.frames), "--frame-range", "#IFRAME#..#IFRAME#",
            "--resume", "-o", f"{args.out}/sky_####.exr"]))
    cuerun.launch(job, use_pycuerun=False)


if __name__ == "__main__":
    main()
