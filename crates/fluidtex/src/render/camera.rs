//! Pinhole cameras.
//!
//! View space: `right`, `up`, `forward` (towards the target) form an
//! orthonormal basis; depth is the distance along `forward`. Pixels follow
//! [`crate::texture`]: pixel `(x, y)` has its centre at `(x + 0.5, y + 0.5)`,
//! row 0 at the top, so a point on the optical axis lands at
//! `(width / 2, height / 2)`. Pixels are square; `fov_y_degrees` is the full
//! vertical field of view.

use glam::{Vec2, Vec3};

/// Points closer than this fraction of the eye–target distance are behind
/// the near plane (clipped). Relative, because meshes come in any units.
pub const NEAR_FRACTION: f32 = 1e-3;

/// A pinhole camera looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    /// Any vector not parallel to the view direction; the image's up is its
    /// component orthogonal to the view direction.
    pub up: Vec3,
    /// Full vertical field of view, degrees, in `(0, 180)`.
    pub fov_y_degrees: f32,
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
}

/// The camera's frame, precomputed for projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct View {
    pub eye: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub forward: Vec3,
    /// Focal length in pixels.
    pub focal: f32,
    /// Image centre in pixels.
    pub centre: Vec2,
    /// Near-plane depth.
    pub near: f32,
}

impl View {
    /// View-space coordinates `(x right, y up, z depth)`.
    #[inline]
    pub fn view_space(&self, p: Vec3) -> Vec3 {
        let d = p - self.eye;
        Vec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.forward))
    }

    /// Pixel coordinates of a view-space point in front of the camera.
    #[inline]
    pub fn pixel(&self, v: Vec3) -> Vec2 {
        Vec2::new(
            self.centre.x + self.focal * v.x / v.z,
            self.centre.y - self.focal * v.y / v.z,
        )
    }

    /// Unit direction of the ray through pixel coordinates `p`.
    #[inline]
    pub fn ray(&self, p: Vec2) -> Vec3 {
        let x = (p.x - self.centre.x) / self.focal;
        let y = (self.centre.y - p.y) / self.focal;
        (self.forward + x * self.right + y * self.up).normalize()
    }
}

impl Camera {
    /// The camera's frame, or `None` when it is degenerate (eye at the
    /// target, `up` parallel to the view direction, a field of view outside
    /// `(0, 180)`, non-finite values or an empty image).
    pub(crate) fn view(&self) -> Option<View> {
        let axis = self.target - self.eye;
        let distance = axis.length();
        let forward = axis.normalize_or_zero();
        let right = forward.cross(self.up).normalize_or_zero();
        let up = right.cross(forward);
        let half = (self.fov_y_degrees * 0.5).to_radians();
        let valid = distance.is_finite()
            && distance > 0.0
            && forward != Vec3::ZERO
            && right != Vec3::ZERO
            && self.eye.is_finite()
            && self.fov_y_degrees > 0.0
            && self.fov_y_degrees < 180.0
            && self.width > 0
            && self.height > 0;
        valid.then(|| View {
            eye: self.eye,
            right,
            up,
            forward,
            focal: 0.5 * self.height as f32 / half.tan(),
            centre: Vec2::new(0.5 * self.width as f32, 0.5 * self.height as f32),
            near: NEAR_FRACTION * distance,
        })
    }

    /// Pixel coordinates and depth (distance along the view direction) of
    /// `p`; `None` behind the near plane or for a degenerate camera. The
    /// point may project outside the image.
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32)> {
        let view = self.view()?;
        let v = view.view_space(p);
        (v.z >= view.near).then(|| (view.pixel(v), v.z))
    }

    /// A camera looking along `view_dir` at the centre of the box, far
    /// enough that the box's bounding sphere fits the image with a 5%
    /// margin; vertical field of view 35°. `up` is +Y, or +Z when looking
    /// (nearly) along Y. A zero or non-finite `view_dir` looks along −Z, and
    /// an empty box is framed as if it had unit size.
    pub fn framing(
        bbox_min: Vec3,
        bbox_max: Vec3,
        view_dir: Vec3,
        width: u32,
        height: u32,
    ) -> Camera {
        const FOV_Y: f32 = 35.0;
        let centre = 0.5 * (bbox_min + bbox_max);
        let radius = 0.5 * (bbox_max - bbox_min).length();
        let radius = if radius.is_finite() && radius > 0.0 {
            radius
        } else {
            1.0
        };
        let dir = view_dir.normalize_or_zero();
        let dir = if dir == Vec3::ZERO || !dir.is_finite() {
            Vec3::NEG_Z
        } else {
            dir
        };
        let up = if dir.dot(Vec3::Y).abs() > 0.99 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let half_y = (0.5 * FOV_Y).to_radians();
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        let half_x = (half_y.tan() * aspect).atan();
        let distance = 1.05 * radius / half_x.min(half_y).sin();
        Camera {
            eye: centre - dir * distance,
            target: centre,
            up,
            fov_y_degrees: FOV_Y,
            width,
            height,
        }
    }
}
