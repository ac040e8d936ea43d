"""The showcase's choices that need no Blender (scripts/showcase.py imports them; tests/python/test_tissues_showcase.py
tests them under plain Python): the labels file of a resolution, the body rigged from its labels (also for
benchmarks/arm_pieces_eval.py), which BVH frames show the walk (half a stride or a whole cycle), which rendered frames go on a video's contact sheet, and the ffmpeg command that encodes the frames."""
import os
import shutil

import numpy as np

import volrig
from volrig import pipeline

MM = (4, 2, 1)  # the Visible Human label maps beside each other in ../shared/data/visible-human


def labels_for(mm: int, data: str) -> str:
    """The AustinMan label map at ``mm`` millimetres under the data root ``data``."""
    if mm not in MM:
        raise SystemExit(f"showcase: --mm {mm}: the Visible Human labels come at {', '.join(map(str, MM))} mm")
    return os.path.join(data, "visible-human", f"austinman_{mm}mm_labels.nii.gz")


def body_of(labels, table):
    """The body: every voxel whose code is not outside (0, or named like external air by the table)."""
    outside = np.isin(labels.array, volrig.tissues.outside_codes(table))
    return volrig.Volume(~outside, labels.spacing, labels.origin)


def rig_labels(labels, table, tissues, thinness: float, kind: str, up, rigid_bone: bool = True):
    """(the body, pipeline.rig_skeleton's result) of a label map rigged as the showcase rigs it: the body's
    skeleton at `thinness` voxels, the tissue table's bone rigid (the rigid layer, issue 18) when `rigid_bone`."""
    body = body_of(labels, table)
    sk = pipeline.skeleton_of(body)
    points = pipeline.skeleton_points(sk, thinness=pipeline.thinness_from_voxels(thinness, sk.metric, body.spacing))
    del sk
    bone = [t for t in tissues if t.name == "bone"] if rigid_bone else []
    rigid = volrig.rigid_tissue(labels, labels=bone[0].codes) if bone else None
    return body, pipeline.rig_skeleton(points, body, kind=kind, up=up, rigid=rigid)


def spread(span: int, count: int) -> list:
    """``count`` frames (0-based) spread over the first ``span``: the fallback without steps."""
    return [round(k * (span - 1) / max(count, 1)) for k in range(count)]


def extremes(ahead, width: int = 6, share: float = 0.25) -> list:
    """The feet's turns: (index, +1 / -1) of each local maximum / minimum of ``ahead`` (one foot ahead of the other
    along the walk, per candidate frame) over ``width`` candidates either side, at least ``share`` of the half range
    away from the middle, in order and alternating (of two turns of one kind in a row the farther is kept)."""
    a = np.asarray(ahead, dtype=float)
    if a.size < 3:
        return []
    middle, half = (a.max() + a.min()) / 2, (a.max() - a.min()) / 2
    found = []
    for i in range(1, a.size - 1):  # (not the ends: the turn may lie beyond them)
        window = a[max(i - width, 0):i + width + 1]
        for kind, best in ((1, window.max()), (-1, window.min())):
            if a[i] == best and kind * (a[i] - middle) >= share * half:
                if found and found[-1][1] == kind:
                    if kind * a[i] > kind * a[found[-1][0]]:
                        found[-1] = (i, kind)
                elif not found or found[-1][0] != i:
                    found.append((i, kind))
    return found


def walk_frames(ahead, candidates, count: int, cycle: bool = False) -> list:
    """``count`` BVH frames (0-based) of the walk from ``ahead`` sampled at ``candidates`` (BVH frames, rising):

    - half a stride (``cycle`` False): from the pose with one foot farthest ahead to the pose with the other, both
      ends included (the contact sheet's four poses);
    - a whole cycle (``cycle`` True): from one foot's turn through the other's back to the first's, the last turn
      left out so the frames loop (frame ``count`` + 1 would be the first again): two steps. The cycle starts at the
      half stride's first turn when a whole cycle follows it in the candidates, else at the turn nearest it that
      a whole cycle follows.

    None when the feet do not turn (the caller spreads the frames instead)."""
    ahead = np.asarray(ahead, dtype=float)
    if ahead.size < 2:
        return None
    if not cycle:
        a, b = sorted((int(np.argmin(ahead)), int(np.argmax(ahead))))
        if b == a:
            return None
        return [candidates[a] + round(k * (candidates[b] - candidates[a]) / max(count - 1, 1)) for k in range(count)]
    turns = extremes(ahead)
    if len(turns) < 3:
        return None
    first = sorted((int(np.argmin(ahead)), int(np.argmax(ahead))))[0]
    start = min(range(len(turns) - 2), key=lambda j: abs(turns[j][0] - first))
    a, c = candidates[turns[start][0]], candidates[turns[start + 2][0]]
    return [a + round(k * (c - a) / max(count, 1)) for k in range(count)]


def sheet_subset(n: int, k: int) -> list:
    """``k`` of ``n`` frames (0-based) evenly spread from the first, for a contact sheet (all of them if n <= k)."""
    if n <= k:
        return list(range(n))
    return sorted({round(j * n / k) for j in range(k)})


def ffmpeg_path() -> str:
    """ffmpeg on PATH, or SystemExit saying how to install it."""
    found = shutil.which("ffmpeg")
    if found is None:
        raise SystemExit("showcase: --video needs ffmpeg, which is not on PATH: install Debian's (apt-get install -y "
                         "ffmpeg; scripts/setup does) and run again")
    return found


def ffmpeg_command(pattern: str, out: str, fps: float = 24, crf: int = 28, loops: int = 1,
                   ffmpeg: str = "ffmpeg") -> list:
    """The command encoding the PNG sequence ``pattern`` (``frame_%03d.png``, numbered from 1) into ``out``: H.264
    (libx264, yuv420p for every player, CRF ``crf``), ``fps`` frames a second, the sequence played ``loops``
    times, the index at the front (+faststart) so a browser plays it while it loads."""
    if loops < 1:
        raise SystemExit(f"showcase: --loops {loops}: at least 1")
    return [ffmpeg, "-y", "-loglevel", "error", "-framerate", f"{fps:g}", "-stream_loop", str(loops - 1),
            "-start_number", "1", "-i", pattern, "-c:v", "libx264", "-preset", "slow", "-crf", str(int(crf)),
            "-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-movflags", "+faststart", out]


def grid(rows, labels, out, title, cell=(2.4, 4.2), crop=None):
    """Rows of (image, caption) as one PNG, each row's label at its left; ``cell``: inches a picture, ``crop``:
    (first, last) columns of each picture kept."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    n = max(len(r) for r in rows)
    fig, axes = plt.subplots(len(rows), n, figsize=(cell[0] * n, cell[1] * len(rows)), squeeze=False)
    for r, (row, label) in enumerate(zip(rows, labels)):
        for c in range(n):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            for side in ax.spines.values():
                side.set_visible(False)
            if c < len(row):
                img = mpimg.imread(row[c][0])
                ax.imshow(img if crop is None else img[:, crop[0]:crop[1] + 1])
                ax.set_title(row[c][1], fontsize=9)
        axes[r][0].set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.savefig(out, dpi=100, bbox_inches="tight")
    plt.close(fig)


def body_columns(paths, pad=0.08):
    """(first, last) pixel columns where any of the images ``paths`` differs from its background (its corners'
    median), widened by ``pad`` of their width each side: the contact sheet of a wide video keeps the body."""
    import matplotlib.image as mpimg
    lo, hi, width = None, None, 0
    for path in paths:
        img = mpimg.imread(path)[..., :3]
        width = img.shape[1]
        corners = np.concatenate([img[:8, :8].reshape(-1, 3), img[:8, -8:].reshape(-1, 3)])
        cols = np.nonzero((np.abs(img - np.median(corners, axis=0)).sum(axis=2) > 0.08).any(axis=0))[0]
        if cols.size:
            lo = cols[0] if lo is None else min(lo, cols[0])
            hi = cols[-1] if hi is None else max(hi, cols[-1])
    if lo is None:
        return None
    margin = int(pad * (hi - lo + 1))
    return max(int(lo) - margin, 0), min(int(hi) + margin, width - 1)


def video_sheet(pick, out, title, most=6, height=3.6):
    """The contact sheet of a video's frames ``pick`` ((image, caption), in order): rows of at most ``most`` as even
    as they go (8: two rows of 4), each picture cropped to the columns where the frames show the body and
    ``height`` inches high."""
    rows = -(-len(pick) // most)
    per_row = -(-len(pick) // rows)
    crop = body_columns([p for p, _ in pick])
    import matplotlib.image as mpimg
    h, w = mpimg.imread(pick[0][0]).shape[:2]
    aspect = ((crop[1] - crop[0] + 1) if crop else w) / h
    grid([pick[i:i + per_row] for i in range(0, len(pick), per_row)], [""] * rows, out, title,
         cell=(max(height * aspect, 1.0), height), crop=crop)
