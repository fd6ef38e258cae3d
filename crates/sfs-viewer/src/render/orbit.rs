//! An orbit camera around the surface (glam, right-handed, y up).

use super::mesh::Bounds;
use glam::{Mat4, Vec3};

/// Pitch is kept within this of the poles so the up vector never aligns
/// with the view direction.
const MAX_PITCH_RAD: f32 = 89.0 * std::f32::consts::PI / 180.0;

/// Room left around the framed box by [`OrbitCamera::frame`].
const FRAME_MARGIN: f32 = 1.1;

/// A camera orbiting `target_world` at `distance`, in world space.
///
/// At `yaw_rad = pitch_rad = 0` it looks down `-z_world`, i.e. along the
/// photo's optical axis, so a framed surface first appears as in the photo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    /// The point looked at and orbited around (world space).
    pub target_world: Vec3,
    /// Distance from the eye to the target (world units, > 0).
    pub distance: f32,
    /// Rotation of the eye about the world y axis; positive moves the eye
    /// towards `+x_world`.
    pub yaw_rad: f32,
    /// Elevation of the eye above the target, clamped to +-89 degrees.
    pub pitch_rad: f32,
    /// Vertical field of view.
    pub fov_y_rad: f32,
    /// Radius of the framed scene (world units): sets the near and far planes
    /// and the zoom limits.
    pub scene_radius: f32,
}

impl Default for OrbitCamera {
    /// Frames [`Bounds::default`] in a square view with a 40 degree field
    /// of view.
    fn default() -> Self {
        Self::framing(&Bounds::default(), 1.0)
    }
}

impl OrbitCamera {
    /// The default view of `bounds` in a view of width / height `aspect`:
    /// along the photo's optical axis, the box filling the view as the
    /// photo's object fills the photo (see [`Self::frame`]; 40 degree
    /// vertical field of view).
    pub fn framing(bounds: &Bounds, aspect: f32) -> Self {
        let mut camera = Self {
            target_world: Vec3::ZERO,
            distance: 1.0,
            yaw_rad: 0.0,
            pitch_rad: 0.0,
            fov_y_rad: 40f32.to_radians(),
            scene_radius: 1.0,
        };
        camera.frame(bounds, aspect);
        camera
    }

    /// Centres `bounds` and moves the eye so that the box, seen along the
    /// photo's optical axis (`-z_world`), fits a view of width / height
    /// `aspect` with a margin: its near face's width and height fit the
    /// horizontal and vertical field of view. So a deep, slanted surface is
    /// framed by what the photo shows of it, not by its bounding sphere.
    /// Keeps the orientation and field of view; the sphere still sets the
    /// near and far planes and the zoom limits.
    pub fn frame(&mut self, bounds: &Bounds, aspect: f32) {
        let radius = if bounds.radius.is_finite() && bounds.radius > 0.0 {
            bounds.radius
        } else {
            1.0
        };
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let half = 0.5 * (bounds.max_world - bounds.min_world);
        let tan_y = (0.5 * self.fov_y_rad).tan().max(1e-3);
        let fit = (half.y / tan_y).max(half.x / (tan_y * aspect));
        let sphere = FRAME_MARGIN * radius / (0.5 * self.fov_y_rad).sin().max(1e-3);
        let distance = half.z + FRAME_MARGIN * fit;
        self.target_world = bounds.centre_world;
        self.scene_radius = radius;
        self.distance = if distance.is_finite() && fit > 1e-3 * radius {
            distance
        } else {
            sphere
        };
    }

    /// Back to the default view of `bounds` (orientation and framing).
    pub fn reset(&mut self, bounds: &Bounds, aspect: f32) {
        self.yaw_rad = 0.0;
        self.pitch_rad = 0.0;
        self.frame(bounds, aspect);
    }

    /// Turns the eye about the target; pitch is clamped to +-89 degrees, yaw
    /// wraps. Non-finite deltas are ignored.
    pub fn orbit(&mut self, delta_yaw_rad: f32, delta_pitch_rad: f32) {
        if delta_yaw_rad.is_finite() {
            self.yaw_rad = (self.yaw_rad + delta_yaw_rad).rem_euclid(std::f32::consts::TAU);
        }
        if delta_pitch_rad.is_finite() {
            self.pitch_rad =
                (self.pitch_rad + delta_pitch_rad).clamp(-MAX_PITCH_RAD, MAX_PITCH_RAD);
        }
    }

    /// Moves the target in the view plane so that the surface follows a
    /// pointer dragged by `(dx_px, dy_px)` (screen pixels, y down) in a view
    /// `viewport_height_px` tall (exact at the target's depth).
    pub fn pan(&mut self, dx_px: f32, dy_px: f32, viewport_height_px: f32) {
        if !(dx_px.is_finite() && dy_px.is_finite() && viewport_height_px > 0.0) {
            return;
        }
        let world_per_px = 2.0 * self.distance * (0.5 * self.fov_y_rad).tan() / viewport_height_px;
        let world_from_view = self.world_from_view();
        let right = world_from_view.transform_vector3(Vec3::X);
        let up = world_from_view.transform_vector3(Vec3::Y);
        self.target_world += world_per_px * (up * dy_px - right * dx_px);
    }

    /// Divides the distance by `factor` (> 1 moves closer), within 1e-3 to
    /// 1e3 scene radii. Non-finite or non-positive factors are ignored.
    pub fn zoom(&mut self, factor: f32) {
        if factor.is_finite() && factor > 0.0 {
            self.distance =
                (self.distance / factor).clamp(1e-3 * self.scene_radius, 1e3 * self.scene_radius);
        }
    }

    /// Position of the eye (world space).
    pub fn eye_world(&self) -> Vec3 {
        let (sin_yaw, cos_yaw) = self.yaw_rad.sin_cos();
        let (sin_pitch, cos_pitch) = self.pitch_rad.sin_cos();
        self.target_world
            + self.distance * Vec3::new(sin_yaw * cos_pitch, sin_pitch, cos_yaw * cos_pitch)
    }

    /// World space to view space (glam right-handed, y up, looking down `-z`).
    pub fn view_from_world(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye_world(), self.target_world, Vec3::Y)
    }

    /// View space to world space (the inverse of [`Self::view_from_world`]).
    pub fn world_from_view(&self) -> Mat4 {
        self.view_from_world().inverse()
    }

    /// World space to WebGPU clip space (depth 0..1) for a view of width /
    /// height `aspect`; the near and far planes enclose the scene sphere.
    pub fn clip_from_world(&self, aspect: f32) -> Mat4 {
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        let far = self.distance + 2.0 * self.scene_radius;
        let near = (self.distance - 2.0 * self.scene_radius).max(1e-3 * self.distance);
        let clip_from_view =
            glam::camera::rh::proj::directx::perspective(self.fov_y_rad, aspect, near, far);
        clip_from_view * self.view_from_world()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4Swizzles;

    fn bounds() -> Bounds {
        let centre_world = Vec3::new(0.3, -0.2, -5.0);
        Bounds {
            min_world: centre_world - Vec3::ONE,
            max_world: centre_world + Vec3::ONE,
            centre_world,
            radius: 1.5,
        }
    }

    fn ndc(clip_from_world: Mat4, p: Vec3) -> Vec3 {
        let clip = clip_from_world * p.extend(1.0);
        clip.xyz() / clip.w
    }

    #[test]
    fn default_view_centres_the_surface_along_the_optical_axis() {
        let camera = OrbitCamera::framing(&bounds(), 1.0);
        let centre = ndc(camera.clip_from_world(1.5), bounds().centre_world);
        assert!(centre.x.abs() < 1e-5 && centre.y.abs() < 1e-5, "{centre}");
        assert!(centre.z > 0.0 && centre.z < 1.0);
        // Looking down -z: a point further from the photo's camera is deeper,
        // +x_world is to the right, +y_world up.
        let m = camera.clip_from_world(1.0);
        let c = bounds().centre_world;
        assert!(ndc(m, c - 0.5 * Vec3::Z).z > centre.z);
        assert!(ndc(m, c + 0.5 * Vec3::X).x > 0.0);
        assert!(ndc(m, c + 0.5 * Vec3::Y).y > 0.0);
    }

    #[test]
    fn framing_fits_the_box_tightly_at_any_aspect() {
        // A deep, narrow box (a slanted face): 2 wide, 3 tall, 12 deep.
        let (min_world, max_world) = (Vec3::new(-1.0, -1.5, -17.0), Vec3::new(1.0, 1.5, -5.0));
        let centre_world = 0.5 * (min_world + max_world);
        let deep = Bounds {
            min_world,
            max_world,
            centre_world,
            radius: 0.5 * (max_world - min_world).length(),
        };
        for aspect in [0.5, 1.0, 2.0] {
            let m = OrbitCamera::framing(&deep, aspect).clip_from_world(aspect);
            let mut largest = 0.0f32;
            for corner in 0..8 {
                let pick =
                    |bit: usize, lo: f32, hi: f32| if corner >> bit & 1 == 0 { lo } else { hi };
                let p = Vec3::new(
                    pick(0, min_world.x, max_world.x),
                    pick(1, min_world.y, max_world.y),
                    pick(2, min_world.z, max_world.z),
                );
                let q = ndc(m, p);
                assert!(
                    q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && (0.0..=1.0).contains(&q.z),
                    "aspect {aspect}: {p} -> {q}"
                );
                largest = largest.max(q.x.abs()).max(q.y.abs());
            }
            // The near face fills the view up to the margin.
            assert!(largest > 0.85, "aspect {aspect}: {largest}");
        }
        // The bounding sphere would have shown the box much smaller.
        let sphere_distance = FRAME_MARGIN * deep.radius / 20f32.to_radians().sin();
        assert!(OrbitCamera::framing(&deep, 1.0).distance < 0.7 * sphere_distance);
    }

    #[test]
    fn orbit_zoom_and_pan_change_the_view() {
        let start = OrbitCamera::framing(&bounds(), 1.0);
        let before = start.clip_from_world(1.0);

        let mut orbited = start;
        orbited.orbit(0.3, 0.2);
        assert_ne!(orbited.clip_from_world(1.0), before);
        assert!((orbited.eye_world().distance(orbited.target_world) - start.distance).abs() < 1e-4);

        let mut zoomed = start;
        zoomed.zoom(2.0);
        assert!((zoomed.distance - 0.5 * start.distance).abs() < 1e-5);
        assert_ne!(zoomed.clip_from_world(1.0), before);
        zoomed.zoom(f32::NAN);
        zoomed.zoom(-1.0);
        assert!((zoomed.distance - 0.5 * start.distance).abs() < 1e-5);

        // Dragging right by 100 px moves the old target right on screen.
        let mut panned = start;
        panned.pan(100.0, 0.0, 400.0);
        let p = ndc(panned.clip_from_world(1.0), start.target_world);
        assert!((p.x - 0.5).abs() < 1e-4 && p.y.abs() < 1e-4, "{p}");
        panned.pan(0.0, 100.0, 400.0);
        assert!(ndc(panned.clip_from_world(1.0), start.target_world).y < -0.4);

        let mut reset = panned;
        reset.orbit(1.0, 1.0);
        reset.reset(&bounds(), 1.0);
        assert_eq!(reset.clip_from_world(1.0), before);
    }

    #[test]
    fn pitch_is_clamped() {
        let mut camera = OrbitCamera::framing(&bounds(), 1.0);
        camera.orbit(0.0, 10.0);
        assert!((camera.pitch_rad - MAX_PITCH_RAD).abs() < 1e-6);
        camera.orbit(0.0, -20.0);
        assert!((camera.pitch_rad + MAX_PITCH_RAD).abs() < 1e-6);
        assert!(camera.clip_from_world(1.0).is_finite());
    }
}
