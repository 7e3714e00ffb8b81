#!/usr/bin/env python3
"""Ring camera i of N (salvq spec Annex C.2, up = -y) for a 3DGS PLY (Gaussian means) or a
salvq model safetensors (anchor positions origin + voxel_size * voxel). Prints the viewer URL
query string cam=...&target=...&up=0,-1,0&fov=50."""
import math, sys
import numpy as np

def ply_means(path):
    with open(path, 'rb') as f:
        props, n = [], 0
        while True:
            line = f.readline().decode().strip()
            if line.startswith('element vertex'): n = int(line.split()[2])
            elif line.startswith('property float'): props.append(line.split()[2])
            elif line == 'end_header': break
        data = np.frombuffer(f.read(n * 4 * len(props)), dtype='<f4').reshape(n, len(props))
    return data[:, [props.index('x'), props.index('y'), props.index('z')]].astype(np.float64)

def anchors(path):
    from safetensors.numpy import load_file
    d = load_file(path)
    pos = d['geometry.origin'][None, :] + d['geometry.voxel_size'][0] * d['anchor.voxel'].astype(np.float32)
    return pos.astype(np.float32).astype(np.float64)

path, i = sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 0
N, phi, fov = 8, math.radians(20), math.radians(50)
pts = ply_means(path) if path.endswith('.ply') else anchors(path)
n = len(pts); q = int(math.floor(0.01 * (n - 1)))
s = np.sort(pts, axis=0); lo, hi = s[q], s[n - 1 - q]
c = (lo + hi) / 2; R = np.linalg.norm(hi - lo) / 2 or 1.0
D = R / math.sin(fov / 2)
u = np.array([0, -1.0, 0]); a = np.array([0, 0, 1.0]); b = np.array([1.0, 0, 0])
th = 2 * math.pi * i / N
p = c + D * (math.cos(phi) * (math.cos(th) * a + math.sin(th) * b) + math.sin(phi) * u)
f = lambda v: ','.join(f'{x:.6f}' for x in v)
print(f'cam={f(p)}&target={f(c)}&up=0,-1,0&fov=50')
