//! The task environment: a scene in the simulator, seen by the camera.
//! Position action = a pixel; direction actions = unit vectors; each
//! direction returns the labels the paper trains on.
use crate::camera::Camera;
use crate::error::{Result, SimError};
use crate::math::{Mat4, Pose3, Quat, Vec3};
use crate::model::{JointKind, ObjectModel};
use crate::physics::{Articulation, PhysicsConfig};
use crate::render::{
    Frame, RenderMesh, RenderRequest, Renderer, Segment, gripper_mesh, plane_mesh,
};
use crate::scene::{Scene, Task};
use std::sync::Arc;

pub use crate::labels::{DELTA, StepLabels, TrainLabels, labels};

/// The object id used in segment ids.
pub const OBJECT_ID: u32 = 1;

/// Where a pixel lands.
#[derive(Clone, Debug, PartialEq)]
pub enum Pick {
    /// On a link that a movable joint moves.
    Movable {
        /// The surface point under the pixel.
        point_in_world: Vec3,
        /// The surface normal there, facing the camera.
        normal_in_world: Vec3,
        /// The link hit.
        link: usize,
        /// The joint that moves it.
        joint: usize,
    },
    /// Background, floor, gripper or a fixed link: nothing to grasp.
    NoMovableLink,
}

#[derive(Clone, Debug)]
struct Grasp {
    link: usize,
    joint: usize,
    normal_in_link: Vec3,
    point_in_link: Vec3,
    j0: f32,
}

/// One scene: the object on its physics, a camera and a renderer, and the
/// paper's two actions (grasp at a pixel, move along a direction).
pub struct SimEnv {
    scene: Scene,
    model: Arc<ObjectModel>,
    art: Articulation,
    camera: Camera,
    renderer: Box<dyn Renderer>,
    grasp: Option<Grasp>,
}

impl SimEnv {
    /// The scene loaded, checked and posed, its meshes given to `renderer`.
    pub fn new(scene: Scene, camera: Camera, mut renderer: Box<dyn Renderer>) -> Result<Self> {
        let model = Arc::new(scene.load_model()?);
        scene.validate(&model)?;
        let mut art = Articulation::new(
            model.clone(),
            scene.world_from_base(),
            PhysicsConfig::with_profile(scene.physics),
        );
        art.set_joint_positions(&scene.joints)?;
        renderer.load(&render_meshes(&model))?;
        Ok(Self {
            scene,
            model,
            art,
            camera,
            renderer,
            grasp: None,
        })
    }

    /// Same object, another scene: no reloading of meshes.
    pub fn reset(&mut self, scene: Scene) -> Result<()> {
        if scene.object != self.scene.object || scene.pose.scale != self.scene.pose.scale {
            *self = Self::new(
                scene,
                self.camera.clone(),
                std::mem::replace(
                    &mut self.renderer,
                    Box::new(crate::render::CpuRenderer::default()),
                ),
            )?;
            return Ok(());
        }
        scene.validate(&self.model)?;
        self.art = Articulation::new(
            self.model.clone(),
            scene.world_from_base(),
            PhysicsConfig::with_profile(scene.physics),
        );
        self.art.set_joint_positions(&scene.joints)?;
        self.scene = scene;
        self.grasp = None;
        Ok(())
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }
    /// The object, placed and scaled.
    pub fn model(&self) -> &Arc<ObjectModel> {
        &self.model
    }
    /// Its physics.
    pub fn articulation(&self) -> &Articulation {
        &self.art
    }
    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }
    /// Which renderer draws (`wgpu/...` or `cpu`).
    pub fn renderer_name(&self) -> String {
        self.renderer.name()
    }
    /// The joint the grasp moves, if the gripper holds something.
    pub fn grasped_joint(&self) -> Option<usize> {
        self.grasp.as_ref().map(|g| g.joint)
    }
    /// The link the gripper holds.
    pub fn grasped_link(&self) -> Option<usize> {
        self.grasp.as_ref().map(|g| g.link)
    }
    /// The grasped point on the link, where it is now (the gripper may lag
    /// behind it when the reference suction slips).
    pub fn grasp_point_in_world(&self) -> Option<Vec3> {
        let g = self.grasp.as_ref()?;
        Some(
            self.art
                .world_from_link(g.link)
                .transform_point(g.point_in_link),
        )
    }
    /// Joint value at the moment of the grasp (j_0).
    pub fn grasp_start_value(&self) -> Option<f32> {
        self.grasp.as_ref().map(|g| g.j0)
    }
    /// Every joint's value now.
    pub fn joint_positions(&self) -> Vec<f32> {
        self.art.joint_positions()
    }

    /// World poses of the render parts: the links, then the floor, then the
    /// gripper (all zeros while it holds nothing), as `render_meshes` orders them.
    pub fn part_transforms(&self) -> Vec<Mat4> {
        let n = self.model.links.len();
        let mut t: Vec<Mat4> = (0..n)
            .map(|l| self.art.world_from_link(l).to_mat4())
            .collect();
        t.push(Mat4::IDENTITY); // floor plane
        let gripper = match (&self.grasp, self.art.gripper_position()) {
            (Some(g), Some(p)) => {
                let n = self.art.world_from_link(g.link).rotation * g.normal_in_link;
                Pose3::from_parts(p, Quat::from_rotation_arc(Vec3::Z, n)).to_mat4()
            }
            _ => Mat4::ZERO, // hidden
        };
        t.push(gripper);
        t
    }

    /// Renders the current state (with the gripper when it holds something).
    pub fn render(&mut self) -> Result<Frame> {
        let r = self.render_request();
        r.renderer.render(r.camera, &r.part_transforms)
    }

    /// Renders parts posed elsewhere (another environment's
    /// [`SimEnv::part_transforms`] on the same object) through this
    /// environment's camera: pictures at a display size while the policy
    /// sees its own.
    pub fn render_parts(&mut self, part_transforms: &[Mat4]) -> Result<Frame> {
        self.renderer.render(&self.camera, part_transforms)
    }

    /// What [`SimEnv::render`] would draw, as a request for
    /// [`crate::render::render_batch`], which renders many environments in
    /// one submission.
    pub fn render_request(&mut self) -> RenderRequest<'_> {
        let part_transforms = self.part_transforms();
        RenderRequest {
            renderer: &mut *self.renderer,
            camera: &self.camera,
            part_transforms,
        }
    }

    /// Renders the object in another joint state (e.g. the goal) without
    /// changing the simulation.
    pub fn render_joint_state(&mut self, joints: &[f32]) -> Result<Frame> {
        let mut shadow = Articulation::new(
            self.model.clone(),
            self.scene.world_from_base(),
            PhysicsConfig::with_profile(self.scene.physics),
        );
        shadow.set_joint_positions(joints)?;
        let mut t: Vec<Mat4> = (0..self.model.links.len())
            .map(|l| shadow.world_from_link(l).to_mat4())
            .collect();
        t.push(Mat4::IDENTITY);
        t.push(Mat4::ZERO);
        self.renderer.render(&self.camera, &t)
    }

    /// The goal image of a goal scene.
    pub fn render_goal(&mut self) -> Result<Option<Frame>> {
        match self.scene.goal.clone() {
            Some(g) => self.render_joint_state(&g.joints).map(Some),
            None => Ok(None),
        }
    }

    /// The movable joint that moves `link` (its own, or its nearest movable ancestor's).
    pub fn joint_moving_link(&self, link: usize) -> Option<usize> {
        let mut l = link;
        while let Some(j) = self.model.parent_joint_of(l) {
            let joint = self.model.joints.get(j)?;
            if joint.kind.is_movable() {
                return Some(j);
            }
            l = joint.parent;
        }
        None
    }

    /// What is under a pixel of `frame`.
    pub fn pick(&self, frame: &Frame, row: u32, col: u32) -> Result<Pick> {
        if row >= frame.height || col >= frame.width {
            return Err(SimError::InvalidAction(format!(
                "pixel (row {row}, col {col}) outside the {}x{} image",
                frame.height, frame.width
            )));
        }
        let i = frame.index(row, col);
        let Segment::Link {
            object: OBJECT_ID,
            link,
        } = Segment::decode(frame.segmentation.get(i).copied().unwrap_or_default())
        else {
            return Ok(Pick::NoMovableLink);
        };
        let (Some(joint), Some(point)) =
            (self.joint_moving_link(link), frame.point_in_world(row, col))
        else {
            return Ok(Pick::NoMovableLink);
        };
        Ok(Pick::Movable {
            point_in_world: point,
            normal_in_world: Vec3::from(frame.normal_in_world.get(i).copied().unwrap_or_default()),
            link,
            joint,
        })
    }

    /// Position action: grasp what is under the pixel. Returns the pick; the
    /// episode should end when it is `NoMovableLink` (or, in the goal task,
    /// not on the goal joint).
    pub fn step_position(&mut self, frame: &Frame, row: u32, col: u32) -> Result<Pick> {
        if self.grasp.is_some() {
            return Err(SimError::InvalidAction(
                "the position action was already taken in this episode".into(),
            ));
        }
        let pick = self.pick(frame, row, col)?;
        if let Pick::Movable {
            point_in_world,
            normal_in_world,
            link,
            joint,
        } = &pick
        {
            self.art.attach(*point_in_world, *link)?;
            let world_from_link = self.art.world_from_link(*link);
            let normal_in_link = world_from_link.rotation.inverse() * *normal_in_world;
            self.grasp = Some(Grasp {
                link: *link,
                joint: *joint,
                normal_in_link,
                point_in_link: world_from_link.inverse_transform_point(*point_in_world),
                j0: self.art.joint_position(*joint),
            });
        }
        Ok(pick)
    }

    /// True when the pick is acceptable for this scene's task.
    pub fn pick_is_valid(&self, pick: &Pick) -> bool {
        match (pick, self.scene.task, &self.scene.goal) {
            (Pick::NoMovableLink, _, _) => false,
            (Pick::Movable { joint, .. }, Task::Goal, Some(g)) => *joint == g.joint,
            _ => true,
        }
    }

    /// Direction action: move the gripper 0.18 m along `direction` (world frame).
    /// Non-unit vectors are normalised; zero, NaN or infinite ones are an error
    /// and leave the state untouched.
    pub fn step_direction(&mut self, direction: Vec3) -> Result<StepLabels> {
        let Some(g) = self.grasp.clone() else {
            return Err(SimError::InvalidAction(
                "step_direction before a position action".into(),
            ));
        };
        act(&mut self.art, &self.model, &g, direction)
    }

    /// Dense labels: what each of `directions` would do from the current
    /// state, each simulated on a copy of the articulation, so the episode
    /// itself is not disturbed. The same state gives the same labels.
    pub fn probe_directions(&self, directions: &[Vec3]) -> Result<Vec<StepLabels>> {
        let Some(g) = self.grasp.as_ref() else {
            return Err(SimError::InvalidAction(
                "probe_directions before a position action".into(),
            ));
        };
        directions
            .iter()
            .map(|d| act(&mut self.art.duplicate(), &self.model, g, *d))
            .collect()
    }
}

/// One direction action on `art` and its labels: what `step_direction` does
/// to the episode and `probe_directions` to a copy.
fn act(
    art: &mut Articulation,
    model: &ObjectModel,
    g: &Grasp,
    direction: Vec3,
) -> Result<StepLabels> {
    if !direction.is_finite() || direction.length() < 1e-6 {
        return Err(SimError::InvalidAction(format!(
            "direction {direction} must be finite and non-zero"
        )));
    }
    let jm = model.joints.get(g.joint).ok_or_else(|| {
        SimError::InvalidAction(format!("grasped joint {} is not in the model", g.joint))
    })?;
    let out = art.move_gripper(direction.normalize(), g.joint)?;
    Ok(labels(
        out.joint_before,
        out.joint_after,
        g.j0,
        jm.lower,
        jm.upper,
        jm.kind == JointKind::Prismatic,
        out.suction_lost,
    ))
}

/// The object's visuals plus floor and gripper, in part slots: links, then plane, then gripper.
pub fn render_meshes(model: &ObjectModel) -> Vec<RenderMesh> {
    let n = model.links.len();
    let mut meshes: Vec<RenderMesh> = model
        .links
        .iter()
        .enumerate()
        .flat_map(|(l, link)| {
            link.visuals.iter().map(move |v| RenderMesh {
                part: l,
                segment: Segment::link_id(OBJECT_ID, l),
                color: v.color,
                opacity: v.opacity,
                mesh: v.mesh_in_link.clone(),
            })
        })
        .collect();
    meshes.push(plane_mesh(n));
    meshes.push(gripper_mesh(n + 1));
    meshes
}
