"""A simulated world rotated by ANGLE degrees and re-rasterized finer, so its walls are not
axis-aligned: world.pgm (0.05 m) -> upsampled by K (bilinear), rotated (bilinear), thresholded."""
import sys
from pathlib import Path
from PIL import Image
src, out, k, angle = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
im = Image.open(src / "world.pgm").convert("L")
w, h = im.size
big = im.resize((w * k, h * k), Image.BILINEAR)
rot = big.rotate(angle, resample=Image.BILINEAR, expand=True, fillcolor=0)
bw = rot.point(lambda v: 254 if v >= 128 else 0)
out.mkdir(parents=True, exist_ok=True)
bw.save(out / "world.pgm")
(out / "world.yaml").write_text(
    f"image: world.pgm\nmode: trinary\nresolution: {0.05 / k}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
    "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
print(out, bw.size, 0.05 / k)
