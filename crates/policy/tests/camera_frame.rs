//! The observation built from a camera frame, against the pinhole model it
//! claims: validation, back-projection, normals on a curved surface, and
//! nearest-neighbour resizing with matching intrinsics.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests fail by panicking"
)]
use nalgebra::{Matrix3, Matrix4, Rotation3, Unit, Vector3, Vector4};
use umpnet_policy::observation::resize_nearest;
use umpnet_policy::{CameraFrame, build_observation};

const IDENTITY: [[f32; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

/// A camera turned and moved off the world origin, so that no axis of the
/// camera frame is a world axis.
fn tilted_pose() -> [[f32; 4]; 4] {
    let r = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)), 0.7);
    let t = Vector3::new(0.4, -1.1, 0.9);
    let mut m = IDENTITY;
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = r[(i, j)];
        }
        m[i][3] = t[i];
    }
    m
}

/// A camera looking along world +x (its x axis on world y, its y axis on world
/// z), turned 0.2 rad off that. The world components of the view rays then
/// change sign across the image, which a wrong "faces the camera" test shows.
fn looking_along_x() -> [[f32; 4]; 4] {
    let base = Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
    let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.2, 0.3, 1.0)), 0.2);
    let r = turn.matrix() * base;
    let mut m = IDENTITY;
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = r[(i, j)];
        }
    }
    m[0][3] = -1.5;
    m
}

fn frame<'a>(w: usize, h: usize, rgb: &'a [u8], depth: &'a [f32]) -> CameraFrame<'a> {
    CameraFrame {
        width: w,
        height: h,
        rgb,
        depth,
        intrinsics: [50.0, 45.0, 30.0, 21.0],
        world_from_camera: tilted_pose(),
    }
}

fn camera_from_world(f: &CameraFrame<'_>) -> Matrix4<f32> {
    let m = f.world_from_camera;
    Matrix4::from_fn(|i, j| m[i][j]).try_inverse().unwrap()
}

#[test]
fn frames_that_cannot_be_back_projected_are_rejected() {
    let (w, h) = (4, 3);
    let rgb = vec![0u8; w * h * 3];
    let depth = vec![1.0f32; w * h];
    let good = frame(w, h, &rgb, &depth);
    assert!(good.validate().is_ok());
    let with = |intrinsics| CameraFrame { intrinsics, ..good };
    for bad in [
        [0.0, 45.0, 30.0, 21.0],
        [-50.0, 45.0, 30.0, 21.0],
        [50.0, 0.0, 30.0, 21.0],
        [50.0, -45.0, 30.0, 21.0],
        [50.0, 45.0, f32::NAN, 21.0],
        [50.0, 45.0, 30.0, f32::INFINITY],
        [f32::INFINITY, 45.0, 30.0, 21.0],
    ] {
        let err = with(bad).validate().unwrap_err().to_string();
        assert!(
            err.contains("intrinsics") && err.contains("fx, fy > 0"),
            "{bad:?}: {err}"
        );
    }
    let mut pose = good.world_from_camera;
    pose[1][3] = f32::NAN;
    let err = CameraFrame {
        world_from_camera: pose,
        ..good
    }
    .validate()
    .unwrap_err();
    assert!(err.to_string().contains("camera pose"), "{err}");
    let err = CameraFrame {
        depth: &depth[1..],
        ..good
    }
    .validate()
    .unwrap_err();
    assert!(
        err.to_string().contains("depth has 11 values, expected 12"),
        "{err}"
    );
    let err = CameraFrame {
        width: 0,
        rgb: &[],
        depth: &[],
        ..good
    }
    .validate()
    .unwrap_err();
    assert!(err.to_string().contains("zero pixels"), "{err}");
}

#[test]
fn pixels_back_project_onto_their_rays_and_invalid_depths_give_nothing() {
    let (w, h) = (6, 5);
    let rgb: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 256) as u8).collect();
    let mut depth: Vec<f32> = (0..w * h).map(|i| 0.5 + 0.1 * i as f32).collect();
    let invalid = [0.0, -1.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    for (k, d) in invalid.iter().enumerate() {
        depth[7 + k] = *d;
    }
    let f = frame(w, h, &rgb, &depth);
    let obs = build_observation(&f).unwrap();
    let to_camera = camera_from_world(&f);
    let [fx, fy, cx, cy] = f.intrinsics;
    for r in 0..h {
        for c in 0..w {
            let i = r * w + c;
            for k in 0..3 {
                assert!((obs[[r, c, 3 + k]] - rgb[i * 3 + k] as f32 / 255.0).abs() < 1e-6);
            }
            let Some(p) = f.point_in_world(r, c) else {
                assert!(
                    (7..7 + invalid.len()).contains(&i),
                    "pixel {i} has depth {}",
                    depth[i]
                );
                // No depth: no point, no normal, depth 0; the colour stays.
                for k in (0..3).chain(6..10) {
                    assert_eq!(obs[[r, c, k]], 0.0, "pixel {i}, channel {k}");
                }
                continue;
            };
            for k in 0..3 {
                assert_eq!(obs[[r, c, k]], p[k]);
            }
            assert_eq!(obs[[r, c, 9]], depth[i]);
            // Projected back through the camera: the pixel's centre, at its depth.
            let q = to_camera * Vector4::new(p.x, p.y, p.z, 1.0);
            assert!(
                (q.z - depth[i]).abs() < 1e-4,
                "pixel {i}: z {} against depth {}",
                q.z,
                depth[i]
            );
            assert!(
                (fx * q.x / q.z + cx - (c as f32 + 0.5)).abs() < 1e-3,
                "pixel {i} column"
            );
            assert!(
                (fy * q.y / q.z + cy - (r as f32 + 0.5)).abs() < 1e-3,
                "pixel {i} row"
            );
        }
    }
    assert!((f.camera_position() - Vector3::new(0.4, -1.1, 0.9)).norm() < 1e-6);
}

#[test]
fn normals_on_a_sphere_are_its_surface_normals_facing_the_camera() {
    // A ball of radius 0.5, 2 m in front of the camera.
    let (w, h) = (64, 48);
    let (fx, fy, cx, cy) = (60.0f32, 60.0, 32.0, 24.0);
    let (centre, radius) = (Vector3::new(0.0f32, 0.0, 2.0), 0.5f32);
    let mut depth = vec![0.0f32; w * h];
    for r in 0..h {
        for c in 0..w {
            // Ray with z = 1, so the hit's parameter is its depth.
            let ray = Vector3::new((c as f32 + 0.5 - cx) / fx, (r as f32 + 0.5 - cy) / fy, 1.0);
            let (a, b) = (ray.norm_squared(), -2.0 * ray.dot(&centre));
            let disc = b * b - 4.0 * a * (centre.norm_squared() - radius * radius);
            if disc > 0.0 {
                depth[r * w + c] = (-b - disc.sqrt()) / (2.0 * a);
            }
        }
    }
    let rgb = vec![200u8; w * h * 3];
    let f = CameraFrame {
        intrinsics: [fx, fy, cx, cy],
        world_from_camera: looking_along_x(),
        ..frame(w, h, &rgb, &depth)
    };
    let obs = build_observation(&f).unwrap();
    let m = f.world_from_camera;
    let world_from_camera = Matrix4::from_fn(|i, j| m[i][j]);
    let centre_in_world = (world_from_camera * centre.push(1.0)).xyz();
    let mut worst = 0.0f32;
    let mut checked = 0;
    for r in 1..h - 1 {
        for c in 1..w - 1 {
            // Pixels whose neighbours all see the ball; rim pixels are too
            // steep for any difference to be exact.
            let all_hit =
                (r - 1..=r + 1).all(|rr| (c - 1..=c + 1).all(|cc| depth[rr * w + cc] > 0.0));
            let p = f.point_in_world(r, c);
            let (true, Some(p)) = (all_hit, p) else {
                continue;
            };
            let exact = (p - centre_in_world).normalize();
            if exact.dot(&(f.camera_position() - p).normalize()) < 0.5 {
                continue;
            }
            let n = Vector3::new(obs[[r, c, 6]], obs[[r, c, 7]], obs[[r, c, 8]]);
            assert!(
                (n.norm() - 1.0).abs() < 1e-4,
                "pixel ({r}, {c}): |n| = {}",
                n.norm()
            );
            worst = worst.max(n.dot(&exact).clamp(-1.0, 1.0).acos().to_degrees());
            checked += 1;
        }
    }
    assert!(checked > 300, "only {checked} pixels on the ball");
    assert!(worst < 4.0, "a normal {worst:.1} degrees off the ball's");
}

#[test]
fn resizing_takes_the_pixel_under_each_centre_and_keeps_the_rays() {
    // Source 8 x 6; each pixel's red is its column, green its row.
    let (w, h) = (8, 6);
    let rgb: Vec<u8> = (0..h)
        .flat_map(|r| (0..w).flat_map(move |c| [c as u8, r as u8, 9]))
        .collect();
    let depth: Vec<f32> = (0..w * h).map(|i| 1.0 + 0.01 * i as f32).collect();
    let f = frame(w, h, &rgb, &depth);
    let cell = |o: &umpnet_policy::observation::OwnedFrame, r: usize, c: usize| {
        let i = r * o.width + c;
        (o.rgb[i * 3] as usize, o.rgb[i * 3 + 1] as usize, o.depth[i])
    };
    // Halving the width, a third of the height: columns 1, 3, 5, 7 and rows 1, 4.
    let small = resize_nearest(&f, 2, 4).unwrap();
    assert_eq!((small.width, small.height), (4, 2));
    for (r, sr) in [1, 4].into_iter().enumerate() {
        for (c, sc) in [1, 3, 5, 7].into_iter().enumerate() {
            assert_eq!(cell(&small, r, c), (sc, sr, depth[sr * w + sc]));
        }
    }
    // Doubling: each source pixel twice over.
    let big = resize_nearest(&f, 12, 16).unwrap();
    for r in 0..12 {
        for c in 0..16 {
            assert_eq!(cell(&big, r, c).0, c / 2);
            assert_eq!(cell(&big, r, c).1, r / 2);
        }
    }
    // The same size is the same frame.
    let same = resize_nearest(&f, h, w).unwrap();
    assert_eq!(
        (same.rgb.as_slice(), same.depth.as_slice()),
        (rgb.as_slice(), depth.as_slice())
    );
    assert_eq!(same.intrinsics, f.intrinsics);
    // The scaled intrinsics keep each pixel's ray: a resized pixel sees what
    // the source camera sees at the same point of the image, (c + 0.5) * 8/4
    // source columns from the left edge.
    let [fx, fy, cx, cy] = f.intrinsics;
    let to_camera = camera_from_world(&f);
    for (o, sx, sy) in [(&small, 2.0f32, 3.0f32), (&big, 0.5, 0.5)] {
        assert_eq!(o.world_from_camera, f.world_from_camera);
        let view = o.view();
        for r in 0..o.height {
            for c in 0..o.width {
                let p = view.point_in_world(r, c).unwrap();
                let q = to_camera * Vector4::new(p.x, p.y, p.z, 1.0);
                assert!((fx * q.x / q.z + cx - (c as f32 + 0.5) * sx).abs() < 1e-3);
                assert!((fy * q.y / q.z + cy - (r as f32 + 0.5) * sy).abs() < 1e-3);
            }
        }
    }
    let bad = CameraFrame {
        depth: &depth[1..],
        ..f
    };
    assert!(resize_nearest(&bad, 2, 4).is_err());
}
