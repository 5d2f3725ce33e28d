"""Figures beside the report: copied into <report>/figures/ (relative links, so the page opens
from disk), optionally compressed (downscaled, 256-colour palette PNG) for the committed snapshot."""
import shutil
from pathlib import Path


def compress_png(src, dst, max_width: int = 1400, colors: int = 256) -> Path:
    """A smaller PNG of `src`: at most `max_width` pixels wide, palette-quantized. One that already is
    (a figure restored from a snapshot, `make restore`) is copied byte for byte: quantizing again
    would change every committed figure's bytes, and a little of its colour, for nothing."""
    from PIL import Image

    dst = Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    with Image.open(src) as im:
        if im.mode == "P" and im.width <= max_width:
            shutil.copyfile(src, dst)
            return dst
        im = im.convert("RGB")
        if im.width > max_width:
            im = im.resize((max_width, round(im.height * max_width / im.width)), Image.LANCZOS)
        im.quantize(colors=colors, method=Image.Quantize.MEDIANCUT).save(dst, optimize=True)
    return dst


def place(src, out_dir, target: str, compress: bool = False) -> str:
    """Copy (or compress) figure `src` of `target` into out_dir/figures/; returns the relative link."""
    src = Path(src)
    name = f"{target}-{src.name}"
    dst = Path(out_dir) / "figures" / name
    dst.parent.mkdir(parents=True, exist_ok=True)
    if compress and src.suffix.lower() == ".png":
        compress_png(src, dst)
    else:
        shutil.copyfile(src, dst)
    return f"figures/{name}"
