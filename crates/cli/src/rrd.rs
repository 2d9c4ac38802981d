//! Rerun recordings of episodes (`--rrd`, the `rerun` feature): one `.rrd`
//! per episode, on the `step` timeline (0 = the grasp, t = after the t-th
//! direction action).
//!
//! Entities, all in the world frame (z up, metres):
//! - `world/object/link_{l}`: each link's meshes (static, in the link frame)
//!   and its pose at each step;
//! - `world/gripper`: the suction cup's pose and point;
//! - `world/camera`: the camera pose and pinhole, with `color`, `depth` (m)
//!   and `segmentation` images and the grasped `pixel`: what the policy sees;
//! - `world/display`: the same pose drawn again at a display size
//!   (`--picture-size`), with its `color` image and the `grasp` point: what a
//!   person watches;
//! - `world/actions/executed` and `world/actions/candidates`: arrows from the
//!   gripper, candidates scaled by predicted distance and coloured by
//!   predicted AoT (green forward, red back, grey none);
//! - `plot/joint`, `plot/predicted_distance`, `plot/actual_distance`,
//!   `plot/predicted_aot`, `plot/actual_aot`: time series.
use anyhow::{Context, Result};
use std::path::Path;
use umpnet_eval::episode::HookFrame;
use umpnet_sim::camera::Camera;
use umpnet_sim::env::{SimEnv, render_meshes};
use umpnet_sim::math::{Mat4, Vec3};
use umpnet_sim::render::{RendererKind, create_renderer};

/// Candidates drawn per step, the most distance first (as in the pictures).
const SHOWN_CANDIDATES: usize = 16;
const ACTION_LENGTH: f32 = 0.18;

/// Whether `--rrd` can work in this build: it can.
pub fn check(_path: &Path) -> Result<()> {
    Ok(())
}

pub struct Recorder {
    rec: rerun::RecordingStream,
    path: std::path::PathBuf,
    /// The display view's size and renderer, and (from the first frame on)
    /// the scene drawn at that size.
    display: Option<((u32, u32), RendererKind)>,
    display_env: Option<SimEnv>,
}

fn rr_err(path: &Path) -> impl Fn(rerun::RecordingStreamError) -> anyhow::Error + '_ {
    move |e| anyhow::anyhow!("cannot write the Rerun recording {}: {e}", path.display())
}

fn transform(m: &Mat4) -> rerun::Transform3D {
    let (_, rotation, translation) = m.to_scale_rotation_translation();
    rerun::Transform3D::from_translation_rotation(
        translation.to_array(),
        rerun::Quaternion::from_xyzw(rotation.to_array()),
    )
}

fn aot_color(aot: Option<&i8>) -> rerun::Color {
    match aot {
        Some(1) => rerun::Color::from_rgb(40, 170, 60),
        Some(-1) => rerun::Color::from_rgb(210, 50, 40),
        _ => rerun::Color::from_rgb(150, 150, 150),
    }
}

impl Recorder {
    /// Starts a recording written to `path` (created or replaced); with
    /// `display`, each step is also drawn at that size (HEIGHT, WIDTH).
    pub fn create(
        path: &Path,
        name: &str,
        display: Option<((u32, u32), RendererKind)>,
    ) -> Result<Self> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating {}", parent.display()))?;
        }
        let rec = rerun::RecordingStreamBuilder::new("umpnet")
            .recording_name(name)
            .save(path)
            .map_err(|e| {
                anyhow::anyhow!("cannot create the Rerun recording {}: {e}", path.display())
            })?;
        Ok(Self {
            rec,
            path: path.to_owned(),
            display,
            display_env: None,
        })
    }

    /// Logs what the hook sees after one action.
    #[expect(
        clippy::too_many_lines,
        reason = "one entity path after another, in the order the viewer lists them"
    )]
    pub fn log(&mut self, h: &HookFrame<'_>) -> Result<()> {
        let err = rr_err(&self.path);
        let rec = &self.rec;
        if h.t == 0 {
            self.log_static(h)?;
        }
        rec.set_time_sequence("step", h.t as i64);
        let env = h.env;
        let parts = env.part_transforms();
        let links = env.model().links.len();
        for (l, m) in parts.iter().take(links).enumerate() {
            rec.log(format!("world/object/link_{l}"), &transform(m))
                .map_err(&err)?;
        }
        if let Some(p) = env.articulation().gripper_position() {
            if let Some(m) = parts.get(links + 1) {
                rec.log("world/gripper", &transform(m)).map_err(&err)?;
            }
            rec.log(
                "world/gripper_point",
                &rerun::Points3D::new([p.to_array()]).with_radii([0.01]),
            )
            .map_err(&err)?;
        }
        let f = h.frame;
        let size = [f.width, f.height];
        rec.log(
            "world/camera/color",
            &rerun::Image::from_rgb24(f.rgb.clone(), size),
        )
        .map_err(&err)?;
        let depth: Vec<u8> = f.depth.iter().flat_map(|d| d.to_le_bytes()).collect();
        rec.log(
            "world/camera/depth",
            &rerun::DepthImage::from_data_type_and_bytes(
                depth,
                size,
                rerun::datatypes::ChannelDatatype::F32,
            )
            .with_meter(1.0),
        )
        .map_err(&err)?;
        let seg: Vec<u8> = f
            .segmentation
            .iter()
            .flat_map(|s| s.to_le_bytes())
            .collect();
        rec.log(
            "world/camera/segmentation",
            &rerun::SegmentationImage::new(
                seg,
                rerun::components::ImageFormat::segmentation(
                    size,
                    rerun::datatypes::ChannelDatatype::U32,
                ),
            ),
        )
        .map_err(&err)?;
        rec.log(
            "world/camera/pixel",
            &rerun::Points2D::new([(h.pixel.1 as f32 + 0.5, h.pixel.0 as f32 + 0.5)])
                .with_radii([2.0]),
        )
        .map_err(&err)?;
        if let Some(j) = env.grasped_joint()
            && let Some(v) = env.joint_positions().get(j)
        {
            rec.log("plot/joint", &rerun::Scalars::single(f64::from(*v)))
                .map_err(&err)?;
        }
        log_display(rec, &self.path, self.display, &mut self.display_env, h)?;
        let Some(step) = h.step else {
            return Ok(());
        };
        let from = Vec3::from(step.gripper_in_world);
        let executed = Vec3::from(step.record.direction).normalize_or_zero();
        rec.log(
            "world/actions/executed",
            &rerun::Arrows3D::from_vectors([(executed * ACTION_LENGTH).to_array()])
                .with_origins([from.to_array()])
                .with_colors([rerun::Color::from_rgb(30, 90, 230)]),
        )
        .map_err(&err)?;
        let labels = &step.record.labels;
        rec.log(
            "plot/actual_distance",
            &rerun::Scalars::single(f64::from(labels.r_dist)),
        )
        .map_err(&err)?;
        rec.log(
            "plot/actual_aot",
            &rerun::Scalars::single(f64::from(labels.aot)),
        )
        .map_err(&err)?;
        if let Some(c) = &step.candidates {
            let mut order: Vec<usize> = (0..c.directions.len()).collect();
            let d = |k: usize| c.distance.get(k).copied().unwrap_or(0.0);
            order.sort_by(|&a, &b| d(b).total_cmp(&d(a)));
            let maxd = d(order.first().copied().unwrap_or(0)).max(1e-6);
            let shown: Vec<usize> = order.into_iter().take(SHOWN_CANDIDATES).collect();
            let vectors = shown.iter().filter_map(|&k| {
                let dir = Vec3::from(*c.directions.get(k)?).normalize_or_zero();
                Some((dir * ACTION_LENGTH * d(k).max(0.0) / maxd).to_array())
            });
            rec.log(
                "world/actions/candidates",
                &rerun::Arrows3D::from_vectors(vectors.collect::<Vec<_>>())
                    .with_origins(vec![from.to_array(); shown.len()])
                    .with_colors(shown.iter().map(|&k| aot_color(c.aot.get(k)))),
            )
            .map_err(&err)?;
            // The executed direction's own prediction, if it is a candidate.
            if let Some(k) = c.index_of(executed) {
                rec.log(
                    "plot/predicted_distance",
                    &rerun::Scalars::single(f64::from(d(k))),
                )
                .map_err(&err)?;
                if let Some(a) = c.aot.get(k) {
                    rec.log("plot/predicted_aot", &rerun::Scalars::single(f64::from(*a)))
                        .map_err(&err)?;
                }
            }
        }
        Ok(())
    }

    /// The meshes and the camera, once.
    fn log_static(&self, h: &HookFrame<'_>) -> Result<()> {
        let err = rr_err(&self.path);
        let rec = &self.rec;
        let env = h.env;
        rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())
            .map_err(&err)?;
        let links = env.model().links.len();
        for m in render_meshes(env.model()) {
            if m.part >= links {
                continue; // the floor and the gripper are not the object's
            }
            let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
            let [r, g, b] = m.color.map(byte);
            let vertex_color = rerun::Color::from_unmultiplied_rgba(r, g, b, byte(m.opacity));
            let k = m.mesh.positions.len();
            let mesh = rerun::Mesh3D::new(m.mesh.positions.iter().map(|p| p.to_array()))
                .with_triangle_indices(
                    m.mesh
                        .triangles
                        .iter()
                        .map(|t| rerun::TriangleIndices::from(*t)),
                )
                // Glass keeps its opacity in the viewer too.
                .with_vertex_colors(vec![vertex_color; k]);
            // One entity per visual: a link may have several.
            let visual = format!("world/object/link_{}/visual_{}", m.part, m.segment);
            rec.log_static(visual, &mesh).map_err(&err)?;
        }
        log_camera(
            rec,
            &self.path,
            "world/camera",
            env.camera(),
            (h.frame.height, h.frame.width),
        )
    }

    /// Flushes the file; errors that the stream met while writing surface here.
    pub fn finish(self) -> Result<()> {
        self.rec.flush_blocking().map_err(|e| {
            anyhow::anyhow!(
                "cannot write the Rerun recording {}: {e}",
                self.path.display()
            )
        })
    }
}

/// A camera's pose and pinhole (an image of `size`, HEIGHT x WIDTH), once.
fn log_camera(
    rec: &rerun::RecordingStream,
    path: &Path,
    entity: &str,
    camera: &Camera,
    size: (u32, u32),
) -> Result<()> {
    let err = rr_err(path);
    let k = camera.intrinsics();
    rec.log_static(entity, &transform(&camera.world_from_camera().to_mat4()))
        .map_err(&err)?;
    rec.log_static(
        entity,
        &rerun::Pinhole::from_focal_length_and_resolution(
            [k.fx, k.fy],
            [size.1 as f32, size.0 as f32],
        )
        .with_principal_point([k.cx, k.cy]),
    )
    .map_err(&err)?;
    Ok(())
}

/// The scene at the display size, in the same pose as the policy's camera.
fn log_display(
    rec: &rerun::RecordingStream,
    path: &Path,
    display: Option<((u32, u32), RendererKind)>,
    display_env: &mut Option<SimEnv>,
    h: &HookFrame<'_>,
) -> Result<()> {
    let Some((size, renderer)) = display else {
        return Ok(());
    };
    let err = rr_err(path);
    let display = match display_env {
        Some(d) => d,
        None => {
            let camera = Camera::reference(size.0, size.1);
            log_camera(rec, path, "world/display", &camera, size)?;
            let env = SimEnv::new(h.env.scene().clone(), camera, create_renderer(renderer)?)
                .context("drawing the recording's display view")?;
            display_env.insert(env)
        }
    };
    let f = display.render_parts(&h.env.part_transforms())?;
    rec.log(
        "world/display/color",
        &rerun::Image::from_rgb24(f.rgb.clone(), [f.width, f.height]),
    )
    .map_err(&err)?;
    if let Some((x, y)) = h
        .env
        .grasp_point_in_world()
        .and_then(|p| crate::images::project(&f, p))
    {
        rec.log(
            "world/display/grasp",
            &rerun::Points2D::new([(x, y)]).with_radii([4.0]),
        )
        .map_err(&err)?;
    }
    Ok(())
}

/// The entity paths and the number of `step` values in a recording: what
/// the tests read back.
#[cfg(test)]
pub fn read_entities(path: &Path) -> Result<(std::collections::BTreeSet<String>, usize)> {
    use rerun::external::re_log_encoding::Decoder;
    use rerun::log::{Chunk, LogMsg};
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let mut entities = std::collections::BTreeSet::new();
    let mut steps = std::collections::BTreeSet::new();
    for msg in Decoder::<LogMsg>::decode_eager(std::io::BufReader::new(file))
        .map_err(|e| anyhow::anyhow!("{}: not a Rerun recording: {e}", path.display()))?
    {
        let msg = msg.map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        if let LogMsg::ArrowMsg(_, arrow) = msg {
            let chunk = Chunk::from_arrow_msg(&arrow)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            entities.insert(chunk.entity_path().to_string());
            if let Some(column) = chunk.timelines().get(&"step".into()) {
                steps.extend(column.times_raw().iter().copied());
            }
        }
    }
    Ok((entities, steps.len()))
}

// Tests may panic: clippy.toml allows it there.
#[cfg(test)]
mod tests {
    use super::*;
    use umpnet_eval::episode::{EpisodeConfig, run_episode};
    use umpnet_eval::protocol::Protocol;
    use umpnet_sim::camera::Camera;
    use umpnet_sim::objects::Category;
    use umpnet_sim::physics::PhysicsProfile;
    use umpnet_sim::render::{RendererKind, create_renderer};
    use umpnet_sim::scene::Task;

    #[test]
    fn a_recorded_episode_reads_back_with_every_entity_at_every_step() {
        // The shipped model, so the steps carry candidates and predictions.
        let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/umpnet-small");
        let resolved = crate::policies::resolve(
            &[format!("umpnet={}", model.display())],
            None,
            1,
            Task::Goal,
            crate::policies::Overrides::default(),
        )
        .expect("the shipped model (and ONNX Runtime) must load");
        let (_, make) = &resolved.factories[0];
        let (h, w) = resolved.resolutions["umpnet"];
        let scene = umpnet_eval::benchmark::benchmark_scene(
            0,
            Task::Goal,
            Category::Door,
            2,
            0,
            PhysicsProfile::Reference,
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/episode.rrd");
        let mut recorder =
            Recorder::create(&path, "test", Some(((120, 160), RendererKind::Auto))).unwrap();
        let mut hook = |f: &HookFrame<'_>| recorder.log(f).unwrap();
        let mut policy = make().unwrap();
        let ep = run_episode(
            &scene,
            &Camera::reference(h, w),
            create_renderer(RendererKind::Auto).unwrap(),
            policy.as_mut(),
            EpisodeConfig {
                budget: 6,
                seed: 1,
                protocol: Protocol::Paper,
            },
            Some(&mut hook),
        )
        .unwrap();
        recorder.finish().unwrap();
        assert!(
            ep.valid_position && !ep.steps.is_empty(),
            "the episode must move something"
        );
        let (entities, steps) = read_entities(&path).unwrap();
        // The grasp and every direction action are points on the timeline.
        assert_eq!(steps, ep.steps.len() + 1, "{entities:?}");
        let links = (0..)
            .take_while(|l| entities.contains(&format!("/world/object/link_{l}")))
            .count();
        assert!(links >= 2, "link poses missing: {entities:?}");
        for e in [
            "/world/camera",
            "/world/camera/color",
            "/world/camera/depth",
            "/world/camera/segmentation",
            "/world/camera/pixel",
            "/world/display",
            "/world/display/color",
            "/world/display/grasp",
            "/world/gripper",
            "/world/gripper_point",
            "/world/actions/executed",
            "/world/actions/candidates",
            "/plot/joint",
            "/plot/actual_distance",
            "/plot/actual_aot",
            "/plot/predicted_distance",
            "/plot/predicted_aot",
        ] {
            assert!(entities.contains(e), "{e} missing from {entities:?}");
        }
        assert!(
            entities
                .iter()
                .any(|e| e.starts_with("/world/object/link_") && e.contains("/visual_")),
            "meshes missing: {entities:?}"
        );
    }
}
