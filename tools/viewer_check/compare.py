#!/usr/bin/env python3
"""PSNR / mean absolute difference between two same-size PNGs (RGB, 8-bit)."""
import sys
import numpy as np
from PIL import Image
a = np.asarray(Image.open(sys.argv[1]).convert('RGB'), dtype=np.float64)
b = np.asarray(Image.open(sys.argv[2]).convert('RGB'), dtype=np.float64)
assert a.shape == b.shape, (a.shape, b.shape)
mse = ((a - b) ** 2).mean()
psnr = 10 * np.log10(255 ** 2 / mse) if mse > 0 else float('inf')
print(f'{sys.argv[1]} vs {sys.argv[2]}: {a.shape[1]}x{a.shape[0]}  PSNR {psnr:.2f} dB  mean |diff| {np.abs(a-b).mean():.2f}/255  '
      f'pixels within 16/255: {(np.abs(a-b).max(axis=2) <= 16).mean()*100:.1f}%')
