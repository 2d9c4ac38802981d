//! The oracle under a depth camera that misreads glass: what it can and
//! cannot see decides its grasp, as a learned policy's.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    reason = "tests fail by panicking"
)]
use umpnet_eval::Protocol;
use umpnet_eval::episode::{EpisodeConfig, run_episode};
use umpnet_sim::camera::Camera;
use umpnet_sim::render::CpuRenderer;
use umpnet_sim::scene::Task;

#[test]
fn an_oracle_that_sees_no_movable_pixel_makes_the_protocols_wrong_grasp() {
    // Every movable part of the cabinet glazed, seen by a depth camera that
    // reads nothing on glass: no pixel reads as a part that moves, so the
    // oracle grasps a static surface and the episode scores a wrong grasp,
    // as a learned policy's would; with the pane's own depth it grasps.
    use rand::SeedableRng;
    let dir = tempfile::tempdir().unwrap();
    let source = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../sim/tests/data/cabinet.urdf"
    ))
    .unwrap();
    let mut links = source.split("<link name=");
    let mut glazed = links.next().unwrap().to_owned();
    for (k, link) in links.enumerate() {
        let link = if k == 0 {
            link.to_owned() // the base stays opaque
        } else {
            link.replace(
                "</geometry></visual>",
                r#"</geometry><material name="glass"><color rgba="0.6 0.8 0.9 0.3"/></material></visual>"#,
            )
        };
        glazed = format!("{glazed}<link name={link}");
    }
    assert_eq!(
        glazed.matches("0.6 0.8 0.9 0.3").count(),
        3,
        "door, drawer, lid"
    );
    let urdf = dir.path().join("cabinet.urdf");
    std::fs::write(&urdf, glazed).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let scene = umpnet_eval::benchmark::sample_visible_scene(
        &mut rng,
        Task::Exploration,
        None,
        umpnet_sim::scene::ObjectSource::file(&urdf),
        Default::default(),
    )
    .unwrap();
    let episode = |glass_depth| {
        let mut oracle = umpnet_eval::scripted_policy("oracle").unwrap();
        let camera = Camera {
            glass_depth,
            ..Camera::reference(48, 64)
        };
        let config = EpisodeConfig {
            budget: 5,
            seed: 1,
            protocol: Protocol::Paper,
        };
        let renderer = Box::new(CpuRenderer::default());
        run_episode(&scene, &camera, renderer, oracle.as_mut(), config, None).unwrap()
    };
    let blind = episode(umpnet_sim::camera::GlassDepth::Missing);
    assert!(!blind.valid_position, "{:?}", blind.pixel);
    assert_eq!(blind.metrics.novel_state_ratio, 0.0);
    let sighted = episode(umpnet_sim::camera::GlassDepth::Surface);
    assert!(sighted.valid_position && sighted.metrics.novel_state_ratio > 0.0);
}
