//! The seeded scene (Annex B.3.1, B.3.2): primitive surfaces in a box, area-weighted surface
//! samples with normal jitter and roughness, a multi-scale density field that thins them, and the
//! small clusters each accepted sample makes.

use super::detmath::{cos_turns, exp, sincos_turns};
use super::linalg::fsum;
use super::rng::{tag, Stream};

/// The scene box is [BOX_MIN, BOX_MIN + BOX_SIZE)^3 in world units.
pub const BOX_MIN: f64 = -2.0;
pub const BOX_SIZE: f64 = 4.0;
/// Normal-direction jitter of a surface sample, in voxels (standard deviation).
pub const JITTER_VOXELS: f64 = 0.5;
/// Density-field wavelengths in voxels (fine octaves) and the coarse octave's in world units.
pub const DENSITY_WAVELENGTHS_VOXELS: [f64; 3] = [5.0, 15.0, 45.0];
pub const DENSITY_WAVELENGTH_WORLD: f64 = 1.0;
/// d(p) = min(1, exp(DENSITY_CONTRAST * (G(p) - DENSITY_CAP))), G ~ unit variance.
pub const DENSITY_CONTRAST: f64 = 2.0;
pub const DENSITY_CAP: f64 = 0.8;
/// Each accepted sample makes a cluster of 1 + U{0..=CLUSTER_EXTRA} points, spread in the
/// tangent plane with this std (voxels).
pub const CLUSTER_EXTRA: u64 = 2;
pub const CLUSTER_SIGMA_VOXELS: f64 = 0.8;
/// Surface roughness: normal displacement (std, voxels) by waves of these wavelengths.
pub const ROUGHNESS_VOXELS: f64 = 0.8;
pub const ROUGHNESS_WAVELENGTHS_VOXELS: [f64; 2] = [4.0, 10.0];

pub type V3 = [f64; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// Rotation matrix (rows) times a vector.
fn rot(m: &[V3; 3], v: V3) -> V3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// A rotation about z by `yaw` turns after a tilt about x by `tilt` turns.
fn yaw_tilt(yaw: f64, tilt: f64) -> [V3; 3] {
    let (sy, cy) = sincos_turns(yaw);
    let (st, ct) = sincos_turns(tilt);
    // Rz * Rx
    [
        [cy, -sy * ct, sy * st],
        [sy, cy * ct, -cy * st],
        [0.0, st, ct],
    ]
}

/// A uniformly random rotation from a normalised Gaussian quaternion.
fn random_rotation(s: &mut Stream) -> [V3; 3] {
    let q = [s.normal(), s.normal(), s.normal(), s.normal()];
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n < 1e-12 {
        return yaw_tilt(0.0, 0.0);
    }
    salvq_render::camera::rotation_of([q[0] / n, q[1] / n, q[2] / n, q[3] / n])
}

#[derive(Debug, Clone)]
enum Shape {
    /// z = z0 + tx x + ty y over |x|, |y| <= half.
    Ground {
        z0: f64,
        tx: f64,
        ty: f64,
        half: f64,
    },
    Sphere {
        r: f64,
    },
    /// Lateral surface and top cap; local axis z, base at z = 0.
    Cylinder {
        r: f64,
        h: f64,
    },
    /// The six faces of a cuboid centred on the origin.
    Cuboid {
        half: V3,
    },
    /// Torus around the local z axis.
    Torus {
        big: f64,
        small: f64,
    },
}

#[derive(Debug, Clone)]
struct Prim {
    shape: Shape,
    center: V3,
    rot: [V3; 3],
    /// Density multiplier in (0, 1].
    weight: f64,
    area: f64,
}

impl Prim {
    fn new(shape: Shape, center: V3, rot: [V3; 3], weight: f64) -> Prim {
        let tau = std::f64::consts::TAU;
        let area = match shape {
            Shape::Ground { tx, ty, half, .. } => {
                4.0 * half * half * (1.0 + tx * tx + ty * ty).sqrt()
            }
            Shape::Sphere { r } => 2.0 * tau * r * r,
            Shape::Cylinder { r, h } => tau * r * h + 0.5 * tau * r * r,
            Shape::Cuboid { half: e } => 8.0 * (e[0] * e[1] + e[1] * e[2] + e[0] * e[2]),
            Shape::Torus { big, small } => tau * tau * big * small,
        };
        Prim {
            shape,
            center,
            rot,
            weight,
            area,
        }
    }

    /// An area-uniform point and its unit normal, in world coordinates.
    fn sample(&self, s: &mut Stream) -> (V3, V3) {
        let (p, n) = match self.shape {
            Shape::Ground { z0, tx, ty, half } => {
                let x = s.range(-half, half);
                let y = s.range(-half, half);
                let l = (1.0 + tx * tx + ty * ty).sqrt();
                ([x, y, z0 + tx * x + ty * y], [-tx / l, -ty / l, 1.0 / l])
            }
            Shape::Sphere { r } => {
                let z = s.range(-1.0, 1.0);
                let (sp, cp) = sincos_turns(s.uniform());
                let q = (1.0 - z * z).max(0.0).sqrt();
                let n = [q * cp, q * sp, z];
                (scale(n, r), n)
            }
            Shape::Cylinder { r, h } => {
                let lateral = r * h;
                let choose = s.range(0.0, lateral + 0.5 * r * r);
                let (sp, cp) = sincos_turns(s.uniform());
                if choose < lateral {
                    ([r * cp, r * sp, h * s.uniform()], [cp, sp, 0.0])
                } else {
                    let rho = r * s.uniform().sqrt();
                    ([rho * cp, rho * sp, h], [0.0, 0.0, 1.0])
                }
            }
            Shape::Cuboid { half: e } => {
                let areas = [e[1] * e[2], e[0] * e[2], e[0] * e[1]];
                let u = s.range(0.0, areas[0] + areas[1] + areas[2]);
                let axis = if u < areas[0] {
                    0
                } else if u < areas[0] + areas[1] {
                    1
                } else {
                    2
                };
                let side = if s.uniform() < 0.5 { -1.0 } else { 1.0 };
                let mut p = [
                    s.range(-e[0], e[0]),
                    s.range(-e[1], e[1]),
                    s.range(-e[2], e[2]),
                ];
                p[axis] = side * e[axis];
                let mut n = [0.0; 3];
                n[axis] = side;
                (p, n)
            }
            Shape::Torus { big, small } => {
                // Tube angle with density proportional to (big + small cos): rejection, at most 16 tries.
                let (mut st, mut ct) = (0.0, 1.0);
                for _ in 0..16 {
                    (st, ct) = sincos_turns(s.uniform());
                    if s.uniform() * (big + small) <= big + small * ct {
                        break;
                    }
                }
                let (sp, cp) = sincos_turns(s.uniform());
                let ring = big + small * ct;
                ([ring * cp, ring * sp, small * st], [ct * cp, ct * sp, st])
            }
        };
        (add(self.center, rot(&self.rot, p)), rot(&self.rot, n))
    }
}

/// The density field and the surface roughness: sums of random plane waves (Annex B.3.2).
#[derive(Debug, Clone)]
struct DensityField {
    /// (wave vector in turns per world unit, phase in turns, amplitude).
    waves: Vec<(V3, f64, f64)>,
    bumps: Vec<(V3, f64, f64)>,
}

impl DensityField {
    fn new(s: &mut Stream, voxel: f64) -> Self {
        let mut lambdas: Vec<f64> = DENSITY_WAVELENGTHS_VOXELS
            .iter()
            .map(|l| l * voxel)
            .collect();
        lambdas.push(DENSITY_WAVELENGTH_WORLD);
        // Each octave has 3 waves of amplitude sqrt(2/3) / 2: four octaves, unit total variance.
        let amp = (2.0f64 / 3.0).sqrt() * 0.5;
        let mut waves = Vec::new();
        for l in lambdas {
            for _ in 0..3 {
                let d = s.unit3();
                waves.push((scale(d, 1.0 / l), s.uniform(), amp));
            }
        }
        let mut bumps = Vec::new();
        let amp = (1.0f64 / 3.0).sqrt();
        for l in ROUGHNESS_WAVELENGTHS_VOXELS {
            for _ in 0..3 {
                let d = s.unit3();
                bumps.push((scale(d, 1.0 / (l * voxel)), s.uniform(), amp));
            }
        }
        DensityField { waves, bumps }
    }

    /// Roughness displacement field, unit variance.
    fn bump(&self, p: V3) -> f64 {
        fsum(
            self.bumps
                .iter()
                .map(|(k, ph, a)| a * cos_turns(dot(*k, p) + ph)),
        )
    }

    fn density(&self, p: V3) -> f64 {
        let g = fsum(
            self.waves
                .iter()
                .map(|(k, ph, a)| a * cos_turns(dot(*k, p) + ph)),
        );
        exp(DENSITY_CONTRAST * (g - DENSITY_CAP)).min(1.0)
    }
}

/// The seeded scene: primitives, cumulative areas, the ground, the density field.
#[derive(Debug, Clone)]
pub struct Scene {
    prims: Vec<Prim>,
    cumulative: Vec<f64>,
    area: f64,
    ground: (f64, f64, f64),
    density: DensityField,
}

impl Scene {
    /// Lays out the primitives (stream SCENE/0) and the density field (SCENE/1) for voxel size `voxel`.
    pub fn new(seed: u64, voxel: f64) -> Self {
        let mut s = Stream::new(seed, tag::SCENE, 0);
        let z0 = s.range(-1.6, -1.4);
        let (tx, ty) = (s.range(-0.05, 0.05), s.range(-0.05, 0.05));
        let ground_z = |x: f64, y: f64| z0 + tx * x + ty * y;
        let id = yaw_tilt(0.0, 0.0);
        let mut prims = vec![Prim::new(
            Shape::Ground {
                z0,
                tx,
                ty,
                half: 1.9,
            },
            [0.0; 3],
            id,
            s.range(0.3, 0.6),
        )];
        for _ in 0..2 + s.below(3) {
            let r = s.range(0.15, 0.55);
            let (x, y) = (s.range(-1.5, 1.5), s.range(-1.5, 1.5));
            let lift = if s.uniform() < 0.3 {
                s.range(1.0, 2.5)
            } else {
                s.range(0.3, 1.0)
            };
            let c = [x, y, ground_z(x, y) + r * lift];
            prims.push(Prim::new(Shape::Sphere { r }, c, id, s.range(0.4, 1.0)));
        }
        for _ in 0..1 + s.below(3) {
            let (r, h) = (s.range(0.08, 0.35), s.range(0.3, 1.6));
            let (x, y) = (s.range(-1.5, 1.5), s.range(-1.5, 1.5));
            let m = yaw_tilt(s.uniform(), s.range(-0.03, 0.03));
            prims.push(Prim::new(
                Shape::Cylinder { r, h },
                [x, y, ground_z(x, y) - 0.05],
                m,
                s.range(0.4, 1.0),
            ));
        }
        for _ in 0..1 + s.below(3) {
            let e = [s.range(0.15, 0.6), s.range(0.15, 0.6), s.range(0.15, 0.6)];
            let (x, y) = (s.range(-1.4, 1.4), s.range(-1.4, 1.4));
            let m = yaw_tilt(s.uniform(), s.range(-0.02, 0.02));
            prims.push(Prim::new(
                Shape::Cuboid { half: e },
                [x, y, ground_z(x, y) + e[2]],
                m,
                s.range(0.4, 1.0),
            ));
        }
        for _ in 0..s.below(2) {
            let (big, small) = (s.range(0.25, 0.5), s.range(0.06, 0.15));
            let c = [s.range(-1.3, 1.3), s.range(-1.3, 1.3), s.range(-0.8, 1.2)];
            let m = random_rotation(&mut s);
            prims.push(Prim::new(
                Shape::Torus { big, small },
                c,
                m,
                s.range(0.4, 1.0),
            ));
        }
        let mut cumulative = Vec::with_capacity(prims.len());
        let mut area = 0.0;
        for p in &prims {
            area += p.area;
            cumulative.push(area);
        }
        let density = DensityField::new(&mut Stream::new(seed, tag::SCENE, 1), voxel);
        Scene {
            prims,
            cumulative,
            area,
            ground: (z0, tx, ty),
            density,
        }
    }

    /// Total primitive area (world units^2).
    pub fn area(&self) -> f64 {
        self.area
    }

    /// One surface sample: the jittered point if it lies in the box and not below the ground,
    /// with its acceptance probability weight * d(p).
    pub fn sample(&self, s: &mut Stream, voxel: f64) -> Option<(V3, V3, f64)> {
        let u = s.uniform() * self.area;
        let i = self
            .cumulative
            .partition_point(|&c| c <= u)
            .min(self.prims.len() - 1);
        let prim = &self.prims[i];
        let (p, n) = prim.sample(s);
        let bump = ROUGHNESS_VOXELS * self.density.bump(p);
        let p = add(p, scale(n, (bump + JITTER_VOXELS * s.normal()) * voxel));
        let inside = p
            .iter()
            .all(|&c| (BOX_MIN..BOX_MIN + BOX_SIZE).contains(&c));
        let (z0, tx, ty) = self.ground;
        let above = i == 0 || p[2] >= z0 + tx * p[0] + ty * p[1] - 0.5 * voxel;
        (inside && above).then(|| (p, n, prim.weight * self.density.density(p)))
    }

    /// An accepted sample's cluster: 1 + below(CLUSTER_EXTRA + 1) points, the first at `p`,
    /// the others displaced in the tangent plane and jittered along the normal.
    pub fn cluster(&self, s: &mut Stream, voxel: f64, p: V3, n: V3, w: f64, out: &mut Vec<V3>) {
        out.push(p);
        let extra = s.below(CLUSTER_EXTRA + 1);
        if extra == 0 {
            return;
        }
        let a = if n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let t1 = cross(n, a);
        let l = dot(t1, t1).sqrt();
        let t1 = scale(t1, 1.0 / l);
        let t2 = cross(n, t1);
        let sc = CLUSTER_SIGMA_VOXELS * voxel;
        for _ in 0..extra {
            let d = add(scale(t1, sc * s.normal()), scale(t2, sc * s.normal()));
            let q = add(add(p, d), scale(n, JITTER_VOXELS * voxel * s.normal()));
            let keep = s.uniform() < w;
            if keep
                && q.iter()
                    .all(|&c| (BOX_MIN..BOX_MIN + BOX_SIZE).contains(&c))
            {
                out.push(q);
            }
        }
    }
}
