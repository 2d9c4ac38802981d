//! The next action from one RGB-D frame of a real (here: synthetic) camera,
//! through the library API alone.
//!
//!     cargo run --release -p umpnet-policy --example next_action -- models/umpnet-small
use nalgebra::Vector3;
use rand::SeedableRng;
use umpnet_policy::cem::Mode;
use umpnet_policy::observation::resize_nearest;
use umpnet_policy::{CameraFrame, DecisionInput, ModelPackage, UmpnetPolicy, build_observation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "models/umpnet-small".into());
    let package = std::sync::Arc::new(ModelPackage::load(std::path::Path::new(&dir), 1, 1, None)?);
    let policy = UmpnetPolicy::new(package);
    // A 480x640 camera 2 m in front of a grey wall (replace with your camera's data).
    let (w, h) = (640, 480);
    let rgb = vec![160u8; w * h * 3];
    let depth = vec![2.0f32; w * h];
    let frame = CameraFrame {
        width: w,
        height: h,
        rgb: &rgb,
        depth: &depth,
        intrinsics: [462.0, 462.0, 320.0, 240.0],
        world_from_camera: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, -2.0],
            [0.0, -1.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    };
    let (mh, mw) = policy.resolution();
    let small = resize_nearest(&frame, mh, mw)?;
    let obs = build_observation(&small.view())?;
    let position = policy.position(obs.view(), None)?;
    let input = DecisionInput {
        observation: obs.view(),
        reference: obs.view(),
        pixel: position.pixel,
        banned: &[],
        previous: None,
        mode: Mode::Explore,
        joint: None,
        motion: None,
        long_motion: None,
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let decision = policy
        .directions(std::slice::from_ref(&input), std::slice::from_mut(&mut rng))?
        .remove(0);
    let d = decision.direction.unwrap_or(Vector3::zeros());
    println!(
        "grasp pixel {:?} (model resolution {mh}x{mw}); direction ({:.3}, {:.3}, {:.3})",
        position.pixel, d.x, d.y, d.z
    );
    Ok(())
}
