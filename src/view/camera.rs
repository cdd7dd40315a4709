//! The orbit camera: a target point, yaw and pitch around it, a distance. Works in the
//! mesh frame (re-centred f32), so huge world coordinates cost no precision.

use glam::{Mat4, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub target: Vec3,
    /// Radians around +y; 0 looks from +z towards −z.
    pub yaw: f32,
    /// Radians above the horizontal, within ±89°.
    pub pitch: f32,
    pub distance: f32,
    /// Vertical field of view, radians.
    pub fov_y: f32,
    /// Radius of the scene's bounding sphere (for the clip planes).
    pub scene_radius: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            target: Vec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            distance: 3.0,
            fov_y: 45f32.to_radians(),
            scene_radius: 1.0,
        }
    }
}

const MAX_PITCH: f32 = 89.0 * std::f32::consts::PI / 180.0;

impl Camera {
    /// Looks at a sphere of `radius` around `centre` from direction `yaw`, `pitch`, far
    /// enough that the whole sphere is in view.
    pub fn framing(centre: Vec3, radius: f32, yaw: f32, pitch: f32) -> Camera {
        let mut c = Camera {
            target: centre,
            yaw,
            pitch,
            scene_radius: radius.max(1e-6),
            ..Default::default()
        };
        c.frame(centre, radius);
        c
    }

    /// Frame all: the target moves to `centre` and the distance fits `radius`.
    pub fn frame(&mut self, centre: Vec3, radius: f32) {
        let radius = radius.max(1e-6);
        self.target = centre;
        self.scene_radius = radius;
        self.distance = radius / (self.fov_y * 0.5).sin() * 1.05;
    }

    /// Unit vector from the target to the eye.
    pub fn back(&self) -> Vec3 {
        Vec3::new(
            self.yaw.sin() * self.pitch.cos(),
            self.pitch.sin(),
            self.yaw.cos() * self.pitch.cos(),
        )
    }

    pub fn eye(&self) -> Vec3 {
        self.target + self.back() * self.distance
    }

    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Y)
    }

    pub fn proj(&self, aspect: f32) -> Mat4 {
        // Near plane: just inside the scene's sphere when outside it, a small fraction of
        // its size when inside; far plane behind the whole sphere.
        let r = self.scene_radius;
        let near = (self.distance - r * 1.1)
            .max(r * 1e-4)
            .max(self.distance * 1e-4);
        let far = self.distance + r * 1.1;
        glam::camera::rh::proj::directx::perspective(
            self.fov_y,
            aspect.max(1e-6),
            near,
            far.max(near * 2.0),
        )
    }

    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        self.proj(aspect) * self.view()
    }

    /// Orbit by a drag of `dx`, `dy` pixels.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * 0.008;
        self.pitch = (self.pitch + dy * 0.008).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Pan by a drag of `dx`, `dy` pixels in a view `height` pixels tall.
    pub fn pan(&mut self, dx: f32, dy: f32, height: f32) {
        let per_pixel = 2.0 * self.distance * (self.fov_y * 0.5).tan() / height.max(1.0);
        let forward = -self.back();
        let right = forward.cross(Vec3::Y).normalize_or_zero();
        let up = right.cross(forward);
        self.target += (-right * dx + up * dy) * per_pixel;
    }

    /// Zoom by a wheel of `scroll` points (positive: closer).
    pub fn zoom(&mut self, scroll: f32) {
        self.distance = (self.distance * (-scroll * 0.002).exp())
            .clamp(self.scene_radius * 1e-3, self.scene_radius * 100.0);
    }

    /// The ray through pixel `(x, y)` of a `w`×`h` view: origin and unit direction.
    pub fn ray(&self, x: f32, y: f32, w: f32, h: f32) -> (Vec3, Vec3) {
        let inv = self.view_proj(w / h).inverse();
        let ndc_x = 2.0 * x / w - 1.0;
        let ndc_y = 1.0 - 2.0 * y / h;
        let near = inv.project_point3(Vec3::new(ndc_x, ndc_y, 0.0));
        let far = inv.project_point3(Vec3::new(ndc_x, ndc_y, 1.0));
        let eye = self.eye();
        (eye, (far - near).normalize_or_zero())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_centre_ray_hits_the_target_and_corners_project_back() {
        let c = Camera::framing(Vec3::new(1.0, 2.0, 3.0), 2.0, 0.7, 0.3);
        let (o, d) = c.ray(400.0, 300.0, 800.0, 600.0);
        // The target lies on the centre ray: distance from the line below 1e-5 of the
        // camera distance (f32 matrix inversion).
        let to = c.target - o;
        let off = (to - d * to.dot(d)).length();
        assert!(off < 1e-5 * c.distance, "{off}");
        // A point projected to the screen and cast back lies on its ray.
        let p = c.target + Vec3::new(0.3, -0.2, 0.1);
        let ndc = c.view_proj(800.0 / 600.0).project_point3(p);
        let (x, y) = ((ndc.x + 1.0) * 400.0, (1.0 - ndc.y) * 300.0);
        let (o, d) = c.ray(x, y, 800.0, 600.0);
        let to = p - o;
        assert!((to - d * to.dot(d)).length() < 1e-4, "point not on its ray");
    }

    #[test]
    fn framing_keeps_the_whole_sphere_in_view() {
        let c = Camera::framing(Vec3::ZERO, 1.0, 0.0, 0.0);
        let vp = c.view_proj(1.0);
        for p in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            let q = vp.project_point3(p);
            assert!(
                q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && (0.0..=1.0).contains(&q.z),
                "{p} → {q}"
            );
        }
    }
}
