//! Pinhole cameras in 3DGS's convention and the camera ring (spec Annex C.2).
//!
//! A camera looks along its +z axis with +x to the right and +y down (the COLMAP / 3DGS
//! convention); pixel (i, j) samples the image point `(i, j)` and a camera-space point
//! `(x, y, z)` lands at `(fx·x/z + (W − 1)/2, fy·y/z + (H − 1)/2)`, which is what 3DGS's
//! projection matrix followed by `ndc2Pix` computes.
//!
//! The **ring** places N cameras on a circle around a scene's bounds, at an elevation, all
//! looking at the bounds' centre with one vertical field of view, so that anyone can render
//! the same views of a scene (Annex C.2 defines it step by step; [`Ring::camera`] follows it).

use std::fmt;

/// A camera or render setting outside its range (Annex C.2): the tools report it as
/// `RenderSettingInvalid`.
#[derive(Debug, Clone, PartialEq)]
pub struct SettingInvalid {
    /// The setting.
    pub setting: &'static str,
    /// Its value.
    pub value: f64,
    /// The rule broken.
    pub rule: &'static str,
}

impl fmt::Display for SettingInvalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (setting, value, rule) = (self.setting, self.value, self.rule);
        write!(f, "render setting {setting} = {value}: {rule} [§C.2]")
    }
}

impl std::error::Error for SettingInvalid {}

/// A result of this module.
pub type Result<T> = std::result::Result<T, SettingInvalid>;

/// Largest image width or height the renderer accepts.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// A pinhole camera: intrinsics and the world-to-camera transform.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal lengths in pixels.
    pub fx: f32,
    /// Vertical focal length in pixels.
    pub fy: f32,
    /// Camera centre in world space.
    pub position: [f32; 3],
    /// World-to-camera rotation, rows = the camera's right, down and forward axes in world
    /// space: camera point = rotation · (world point − position).
    pub rotation: [[f32; 3]; 3],
}

impl Camera {
    /// `tan` of half the horizontal and vertical fields of view.
    pub fn tan_half_fov(&self) -> [f32; 2] {
        [
            self.width as f32 / (2.0 * self.fx),
            self.height as f32 / (2.0 * self.fy),
        ]
    }

    /// The same camera for a `width × height` image: the focal lengths scale with the sides,
    /// so the fields of view stay (the principal point is always the image centre).
    pub fn resized(&self, width: u32, height: u32) -> Result<Camera> {
        check_image_size(width, height)?;
        Ok(Camera {
            width,
            height,
            fx: (f64::from(self.fx) * f64::from(width) / f64::from(self.width)) as f32,
            fy: (f64::from(self.fy) * f64::from(height) / f64::from(self.height)) as f32,
            ..self.clone()
        })
    }

    /// A world point in camera space.
    pub fn to_camera(&self, p: [f32; 3]) -> [f32; 3] {
        let d = [
            p[0] - self.position[0],
            p[1] - self.position[1],
            p[2] - self.position[2],
        ];
        self.rotation
            .map(|r| r[0] * d[0] + r[1] * d[1] + r[2] * d[2])
    }
}

/// One of the six axis directions, the ring's "up".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Axis {
    /// 0: x, 1: y, 2: z.
    pub index: usize,
    /// +1 or −1.
    pub sign: i8,
}

impl Axis {
    /// Parses `+x`, `-x`, `x`, … `-z`.
    pub fn parse(s: &str) -> Option<Axis> {
        let (sign, name) = match s.as_bytes() {
            [b'-', n] => (-1, *n),
            [b'+', n] | [n] => (1, *n),
            _ => return None,
        };
        let index = match name {
            b'x' => 0,
            b'y' => 1,
            b'z' => 2,
            _ => return None,
        };
        Some(Axis { index, sign })
    }

    fn vector(self) -> [f64; 3] {
        let mut v = [0.0; 3];
        v[self.index] = f64::from(self.sign);
        v
    }
}

/// A robust axis-aligned box around points: per axis, the 1st and 99th percentiles
/// (Annex C.2), so that a few stray Gaussians far away do not shrink the scene to a dot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest corner.
    pub min: [f32; 3],
    /// Largest corner.
    pub max: [f32; 3],
}

/// The fraction of points each side that [`Bounds`] leaves out.
pub const BOUNDS_QUANTILE: f64 = 0.01;

impl Bounds {
    /// Per axis, with the coordinates sorted ascending (`total_cmp`) as `s_0 … s_{n−1}`:
    /// `min = s_q`, `max = s_{n−1−q}`, `q = floor(0.01 · (n − 1))`. No points: the unit cube
    /// around the origin.
    pub fn of_points(points: &[[f32; 3]]) -> Bounds {
        if points.is_empty() {
            return Bounds {
                min: [-0.5; 3],
                max: [0.5; 3],
            };
        }
        let n = points.len();
        let q = (BOUNDS_QUANTILE * (n - 1) as f64).floor() as usize;
        let mut min = [0f32; 3];
        let mut max = [0f32; 3];
        let mut axis: Vec<f32> = Vec::with_capacity(n);
        for a in 0..3 {
            axis.clear();
            axis.extend(points.iter().map(|p| p[a]));
            axis.sort_unstable_by(f32::total_cmp);
            min[a] = axis[q];
            max[a] = axis[n - 1 - q];
        }
        Bounds { min, max }
    }

    /// The box's centre and half its diagonal (1 when the box is a point or not finite).
    pub fn sphere(&self) -> ([f64; 3], f64) {
        let c = [0, 1, 2].map(|a| 0.5 * (f64::from(self.min[a]) + f64::from(self.max[a])));
        let r = 0.5
            * (0..3)
                .map(|a| (f64::from(self.max[a]) - f64::from(self.min[a])).powi(2))
                .sum::<f64>()
                .sqrt();
        if r > 0.0 && r.is_finite() && c.iter().all(|v| v.is_finite()) {
            (c, r)
        } else if c.iter().all(|v| v.is_finite()) {
            (c, 1.0)
        } else {
            ([0.0; 3], 1.0)
        }
    }
}

/// The camera ring (Annex C.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    /// Number of views N on the circle.
    pub views: u32,
    /// Elevation of the cameras above the bounds' centre, degrees, in (−89, 89).
    pub elevation_deg: f64,
    /// Vertical field of view, degrees, in (0, 179).
    pub fov_y_deg: f64,
    /// The scene's up direction (3DGS / COLMAP captures are usually −y up).
    pub up: Axis,
}

impl Default for Ring {
    /// 8 views, 20° elevation, 50° vertical field of view, −y up.
    fn default() -> Ring {
        Ring {
            views: 8,
            elevation_deg: 20.0,
            fov_y_deg: 50.0,
            up: Axis { index: 1, sign: -1 },
        }
    }
}

fn invalid(setting: &'static str, value: f64, rule: &'static str) -> SettingInvalid {
    SettingInvalid {
        setting,
        value,
        rule,
    }
}

/// The rotation matrix of the unit quaternion (w, x, y, z), row-major (COLMAP's
/// `qvec2rotmat`).
pub fn rotation_of(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// Checks an image size: each side 1 … [`MAX_IMAGE_SIDE`].
pub fn check_image_size(width: u32, height: u32) -> Result<()> {
    for (setting, v) in [("width", width), ("height", height)] {
        if v == 0 || v > MAX_IMAGE_SIDE {
            return Err(invalid(
                setting,
                f64::from(v),
                "image sides are 1 … 16384 pixels",
            ));
        }
    }
    Ok(())
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalized(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|v| v / n)
}

impl Ring {
    /// Camera `view` (0 … N − 1) of the ring around `bounds`, for a `width × height` image.
    ///
    /// Annex C.2: centre `c` and radius `R` from [`Bounds::sphere`]; distance
    /// `d = R / sin(fov_y / 2)` (the bounding sphere fills the vertical field of view); up
    /// `u`, horizontal axes `a = e_{(up+1) mod 3}`, `b = e_{(up+2) mod 3}`;
    /// `θ = 2π · view / N`, `φ` = elevation; position
    /// `p = c + d (cos φ (cos θ a + sin θ b) + sin φ u)`; forward `f = (c − p)/|c − p|`,
    /// right `r = (f × u)/|f × u|`, down `f × r`; `fx = fy = H / (2 tan(fov_y / 2))`.
    pub fn camera(&self, bounds: &Bounds, view: u32, width: u32, height: u32) -> Result<Camera> {
        check_image_size(width, height)?;
        if self.views == 0 {
            return Err(invalid("views", 0.0, "a ring has at least one view"));
        }
        if view >= self.views {
            return Err(invalid(
                "view",
                f64::from(view),
                "the view index must be below the number of views",
            ));
        }
        if !(self.elevation_deg > -89.0 && self.elevation_deg < 89.0) {
            return Err(invalid(
                "elevation",
                self.elevation_deg,
                "the elevation is in (-89, 89) degrees",
            ));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 179.0) {
            return Err(invalid(
                "fov",
                self.fov_y_deg,
                "the vertical field of view is in (0, 179) degrees",
            ));
        }
        let (c, r) = bounds.sphere();
        let half_fov = self.fov_y_deg.to_radians() / 2.0;
        let d = r / half_fov.sin();
        let u = self.up.vector();
        let mut a = [0.0; 3];
        a[(self.up.index + 1) % 3] = 1.0;
        let mut b = [0.0; 3];
        b[(self.up.index + 2) % 3] = 1.0;
        let theta = std::f64::consts::TAU * f64::from(view) / f64::from(self.views);
        let phi = self.elevation_deg.to_radians();
        let p: [f64; 3] = std::array::from_fn(|i| {
            c[i] + d * (phi.cos() * (theta.cos() * a[i] + theta.sin() * b[i]) + phi.sin() * u[i])
        });
        let forward = normalized(sub(c, p));
        let right = normalized(cross(forward, u));
        let down = cross(forward, right);
        let focal = f64::from(height) / (2.0 * half_fov.tan());
        let row = |v: [f64; 3]| v.map(|x| x as f32);
        Ok(Camera {
            width,
            height,
            fx: focal as f32,
            fy: focal as f32,
            position: row(p),
            rotation: [row(right), row(down), row(forward)],
        })
    }
}
