//! A model package: three ONNX networks and `model.json` (contract in
//! docs/model-package.md), validated on load. `meta` reads and checks
//! model.json, `onnx` opens a network and checks what it returns; this
//! module loads the package's networks and runs them.
mod meta;
mod onnx;

use crate::error::{PolicyError, Result};
use crate::frame_joint::JOINT_CHANNELS;
use crate::observation::CHANNELS;
pub use meta::{
    Branch, Branches, DirectionFilter, FORMAT_VERSION, Files, GraspRule, InputSpec, MAX_EMBEDDING,
    MAX_SIDE, ModelMeta, Variant,
};
use ndarray::{Array1, Array2, Array3, Array4, ArrayView2, ArrayView4, Axis};
use onnx::{check_io, finite, in_range, open_network, ort_err, output};
use ort::session::Session;
use ort::value::TensorRef;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// How far below zero a regressed distance may come (metres) before the
/// network counts as broken.
pub const MAX_DISTANCE_NOISE: f32 = 0.05;
/// Scores of candidate directions: distance >= 0 and AoT class probabilities (-1, 0, +1).
#[derive(Clone, Debug)]
pub struct DirectionScores {
    /// Predicted joint change per candidate.
    pub distance: Array1<f32>,
    /// Candidates x 3: probabilities of AoT -1, 0, +1.
    pub aot_probs: Array2<f32>,
}

struct Sessions {
    position: Session,
    encoder: Session,
    decoder: Session,
    joint: Option<Session>,
}

/// A loaded model package: its three networks in ONNX Runtime sessions,
/// checked against model.json.
pub struct ModelPackage {
    /// The package's folder.
    pub dir: PathBuf,
    /// model.json.
    pub meta: ModelMeta,
    /// What the decoder outputs, and so how candidates are ranked.
    pub branches: Branches,
    /// Session sets, one per concurrent user.
    pool: Vec<Mutex<Sessions>>,
    decoder_outputs: Vec<String>,
}

pub(crate) fn pkg_err(path: &Path, what: impl Into<String>) -> PolicyError {
    PolicyError::Package {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

impl ModelPackage {
    /// Loads and validates a package with `sessions` concurrent session sets
    /// and `threads` intra-op threads each.
    pub fn load(
        dir: &Path,
        sessions: usize,
        threads: usize,
        ort_library: Option<&Path>,
    ) -> Result<Self> {
        let meta_path = dir.join("model.json");
        let meta = ModelMeta::read(&meta_path)?;
        let (branches, decoder_outputs) = meta.decoder(&meta_path)?;
        let env = crate::runtime::environment(ort_library)?;
        let (h, w, e) = (
            meta.input.height as i64,
            meta.input.width as i64,
            meta.embedding as i64,
        );
        let c = CHANNELS as i64;
        let mut pool = Vec::new();
        for _ in 0..sessions.max(1) {
            let open = |name: &str| open_network(env, dir, &meta_path, name, threads);
            let (pf, position) = open(&meta.files.position)?;
            check_io(
                &pf,
                &position,
                &[("observation", vec![-1, h, w, c])],
                &[("affordance", vec![-1, h, w])],
            )?;
            let (ef, encoder) = open(&meta.files.direction_encoder)?;
            check_io(
                &ef,
                &encoder,
                &[
                    ("observation", vec![-1, h, w, c]),
                    ("reference", vec![-1, h, w, c]),
                    ("pixel", vec![-1, 2]),
                ],
                &[
                    ("dist_embedding", vec![-1, e]),
                    ("aot_embedding", vec![-1, e]),
                ],
            )?;
            let (df, decoder) = open(&meta.files.direction_decoder)?;
            let outs: Vec<(&str, Vec<i64>)> = decoder_outputs
                .iter()
                .map(|n| {
                    (
                        n.as_str(),
                        if n == "aot_probs" || n == "predicted_direction" {
                            vec![-1, 3]
                        } else {
                            vec![-1]
                        },
                    )
                })
                .collect();
            let mut dec_inputs = vec![
                ("dist_embedding", vec![-1, e]),
                ("aot_embedding", vec![-1, e]),
            ];
            if branches != Branches::Inverse {
                dec_inputs.push(("direction", vec![-1, 3]));
            }
            check_io(&df, &decoder, &dec_inputs, &outs)?;
            let joint = match &meta.files.joint {
                Some(name) => {
                    let (jf, joint) = open(name)?;
                    check_io(
                        &jf,
                        &joint,
                        &[("observation", vec![-1, h, w, c])],
                        &[("joint_fields", vec![-1, JOINT_CHANNELS as i64, h, w])],
                    )?;
                    Some(joint)
                }
                None => None,
            };
            pool.push(Mutex::new(Sessions {
                position,
                encoder,
                decoder,
                joint,
            }));
        }
        let pkg = Self {
            dir: dir.to_path_buf(),
            meta,
            branches,
            pool,
            decoder_outputs,
        };
        pkg.probe()?;
        Ok(pkg)
    }

    /// One dummy run through every network (batch 1, zeros) with the shapes of
    /// its outputs checked against model.json. ONNX files keep the batch and
    /// other dimensions dynamic, so a package whose embedding or candidate width
    /// disagrees with model.json passes the static checks and would fail on its
    /// first real input; here it fails at load, naming the file and the tensor.
    fn probe(&self) -> Result<()> {
        let (h, w, e) = (
            self.meta.input.height,
            self.meta.input.width,
            self.meta.embedding,
        );
        let check = |file: &str, tensor: &str, found: &[usize], expected: &[usize]| {
            if found == expected {
                Ok(())
            } else {
                Err(pkg_err(
                    &self.dir.join(file),
                    format!(
                        "output `{tensor}` has shape {found:?} on a batch of 1, expected {expected:?} (from model.json)"
                    ),
                ))
            }
        };
        let files = &self.meta.files;
        let obs = ndarray::Array4::<f32>::zeros((1, h, w, CHANNELS));
        let pixel = ndarray::arr2(&[[(h / 2) as i64, (w / 2) as i64]]);
        let affordance = self.position(obs.view())?;
        check(
            &files.position,
            "affordance",
            affordance.shape(),
            &[1, h, w],
        )?;
        if let (Some(file), Some(fields)) = (&files.joint, self.joint_fields(obs.view())?) {
            check(
                file,
                "joint_fields",
                fields.shape(),
                &[1, JOINT_CHANNELS, h, w],
            )?;
        }
        let (de, ae) = self.encode(obs.view(), obs.view(), pixel.view())?;
        check(
            &files.direction_encoder,
            "dist_embedding",
            de.shape(),
            &[1, e],
        )?;
        check(
            &files.direction_encoder,
            "aot_embedding",
            ae.shape(),
            &[1, e],
        )?;
        if self.branches == Branches::Inverse {
            let d = self.predict_direction(de.view(), ae.view())?;
            return check(
                &files.direction_decoder,
                "predicted_direction",
                d.shape(),
                &[1, 3],
            );
        }
        let dirs = ndarray::arr2(&[[1.0f32, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let (de2, ae2) = (
            ndarray::concatenate![Axis(0), de, de],
            ndarray::concatenate![Axis(0), ae, ae],
        );
        let scores = self.decode(de2.view(), ae2.view(), dirs.view())?;
        let name = self.decoder_outputs.first().map_or("", String::as_str);
        check(
            &files.direction_decoder,
            name,
            scores.distance.shape(),
            &[2],
        )?;
        check(
            &files.direction_decoder,
            "aot_probs",
            scores.aot_probs.shape(),
            &[2, 3],
        )
    }

    fn with_sessions<T>(&self, f: impl FnOnce(&mut Sessions) -> Result<T>) -> Result<T> {
        for m in &self.pool {
            if let Ok(mut s) = m.try_lock() {
                return f(&mut s);
            }
        }
        let mut s = self
            .pool
            .first()
            .ok_or_else(|| PolicyError::Runtime("no inference sessions".into()))?
            .lock()
            .map_err(|_| PolicyError::Runtime("session lock poisoned".into()))?;
        f(&mut s)
    }

    fn check_obs(&self, what: &str, obs: &ArrayView4<'_, f32>) -> Result<()> {
        let i = &self.meta.input;
        let (_, h, w, c) = obs.dim();
        if [h, w, c] != [i.height, i.width, CHANNELS] {
            return Err(PolicyError::Input(format!(
                "{what} has shape {:?}, the model takes [batch, {}, {}, {CHANNELS}]",
                obs.shape(),
                i.height,
                i.width
            )));
        }
        Ok(())
    }

    /// Affordance in [0, 1] per pixel: batch x H x W.
    pub fn position(&self, observation: ArrayView4<'_, f32>) -> Result<Array3<f32>> {
        self.check_obs("observation", &observation)?;
        self.with_sessions(|s| {
            let file = self.dir.join(&self.meta.files.position);
            let o = observation.as_standard_layout();
            let input =
                TensorRef::from_array_view(o.view().into_dyn()).map_err(|e| ort_err(&file, e))?;
            let out = s
                .position
                .run(ort::inputs!["observation" => input])
                .map_err(|e| ort_err(&file, e))?;
            let a = output(&out, "affordance", &file)?
                .try_extract_array::<f32>()
                .map_err(|e| ort_err(&file, e))?;
            let a = a
                .to_owned()
                .into_dimensionality()
                .map_err(|e| ort_err(&file, e))?;
            finite(a, &file, "affordance")
        })
    }

    /// Whether the package has a JointNet (`files.joint`).
    pub fn has_joint(&self) -> bool {
        self.meta.files.joint.is_some()
    }

    /// The JointNet's per-pixel outputs (batch x [`JOINT_CHANNELS`] x H x W),
    /// or None when the package has no JointNet.
    pub fn joint_fields(&self, observation: ArrayView4<'_, f32>) -> Result<Option<Array4<f32>>> {
        let Some(name) = &self.meta.files.joint else {
            return Ok(None);
        };
        self.check_obs("observation", &observation)?;
        self.with_sessions(|s| {
            let file = self.dir.join(name);
            let Some(session) = s.joint.as_mut() else {
                return Err(PolicyError::Runtime(format!(
                    "{}: no session for the JointNet",
                    file.display()
                )));
            };
            let o = observation.as_standard_layout();
            let input =
                TensorRef::from_array_view(o.view().into_dyn()).map_err(|e| ort_err(&file, e))?;
            let out = session
                .run(ort::inputs!["observation" => input])
                .map_err(|e| ort_err(&file, e))?;
            let a = output(&out, "joint_fields", &file)?
                .try_extract_array::<f32>()
                .map_err(|e| ort_err(&file, e))?
                .to_owned()
                .into_dimensionality::<ndarray::Ix4>()
                .map_err(|e| ort_err(&file, e))?;
            let (n, h, w, _) = observation.dim();
            let want = [n, crate::frame_joint::JOINT_CHANNELS, h, w];
            if a.shape() != want {
                return Err(PolicyError::Runtime(format!(
                    "{}: `joint_fields` has shape {:?}, expected {want:?} (batch, channels, \
                     height, width)",
                    file.display(),
                    a.shape()
                )));
            }
            finite(a, &file, "joint_fields").map(Some)
        })
    }

    /// Image embeddings at the grasp pixels: (dist, aot), each batch x E.
    pub fn encode(
        &self,
        observation: ArrayView4<'_, f32>,
        reference: ArrayView4<'_, f32>,
        pixel: ArrayView2<'_, i64>,
    ) -> Result<(Array2<f32>, Array2<f32>)> {
        self.check_obs("observation", &observation)?;
        self.check_obs("reference", &reference)?;
        let batch = observation.len_of(Axis(0));
        if pixel.shape() != [batch, 2] {
            return Err(PolicyError::Input(format!(
                "pixel has shape {:?}, expected [{batch}, 2]",
                pixel.shape(),
            )));
        }
        self.with_sessions(|s| {
            let file = self.dir.join(&self.meta.files.direction_encoder);
            let e = |e: ort::Error| ort_err(&file, e);
            let o = observation.as_standard_layout();
            let r = reference.as_standard_layout();
            let p = pixel.as_standard_layout();
            let out = s
                .encoder
                .run(ort::inputs![
                    "observation" => TensorRef::from_array_view(o.view().into_dyn()).map_err(e)?,
                    "reference" => TensorRef::from_array_view(r.view().into_dyn()).map_err(e)?,
                    "pixel" => TensorRef::from_array_view(p.view().into_dyn()).map_err(e)?,
                ])
                .map_err(e)?;
            let get = |n: &str| -> Result<Array2<f32>> {
                let a = output(&out, n, &file)?
                    .try_extract_array::<f32>()
                    .map_err(e)?
                    .to_owned()
                    .into_dimensionality()
                    .map_err(|x| ort_err(&file, x))?;
                finite(a, &file, n)
            };
            Ok((get("dist_embedding")?, get("aot_embedding")?))
        })
    }

    /// Scores candidates: rows of the embeddings pair with rows of `direction`.
    pub fn decode(
        &self,
        dist_embedding: ArrayView2<'_, f32>,
        aot_embedding: ArrayView2<'_, f32>,
        direction: ArrayView2<'_, f32>,
    ) -> Result<DirectionScores> {
        if self.branches == Branches::Inverse {
            return Err(PolicyError::Input(format!(
                "{}: an Inverse package predicts one direction (predict_direction); it scores no candidates",
                self.dir.display()
            )));
        }
        let n = direction.nrows();
        let e = self.meta.embedding;
        if dist_embedding.shape() != [n, e]
            || aot_embedding.shape() != [n, e]
            || direction.shape() != [n, 3]
        {
            return Err(PolicyError::Input(format!(
                "decoder inputs: embeddings {:?}/{:?} and directions {:?}, expected [{n}, {e}] and [{n}, 3]",
                dist_embedding.shape(),
                aot_embedding.shape(),
                direction.shape()
            )));
        }
        self.with_sessions(|s| {
            let file = self.dir.join(&self.meta.files.direction_decoder);
            let er = |x: ort::Error| ort_err(&file, x);
            let (a, b, c) = (dist_embedding.as_standard_layout(), aot_embedding.as_standard_layout(), direction.as_standard_layout());
            let out = s
                .decoder
                .run(ort::inputs![
                    "dist_embedding" => TensorRef::from_array_view(a.view().into_dyn()).map_err(er)?,
                    "aot_embedding" => TensorRef::from_array_view(b.view().into_dyn()).map_err(er)?,
                    "direction" => TensorRef::from_array_view(c.view().into_dyn()).map_err(er)?,
                ])
                .map_err(er)?;
            let get1 = |k: &str| -> Result<Array1<f32>> {
                let a = output(&out, k, &file)?.try_extract_array::<f32>().map_err(er)?.to_owned().into_dimensionality().map_err(|x| ort_err(&file, x))?;
                let a = finite(a, &file, k)?;
                in_range(&a, &file, k, match k {
                    // A distance is a magnitude, regressed: a little below 0 is
                    // the regression's noise, a lot is a broken network.
                    "distance" => (-MAX_DISTANCE_NOISE, f32::INFINITY),
                    "success_prob" => (0.0, 1.0),
                    _ => (f32::NEG_INFINITY, f32::INFINITY),
                })?;
                Ok(a)
            };
            let get2 = |k: &str| -> Result<Array2<f32>> {
                let a = output(&out, k, &file)?.try_extract_array::<f32>().map_err(er)?.to_owned().into_dimensionality().map_err(|x| ort_err(&file, x))?;
                let a = finite(a, &file, k)?;
                in_range(&a, &file, k, (0.0, 1.0))?;
                Ok(a)
            };
            // Columns in the package's class order -> canonical (-1, 0, +1).
            let canonical = |p: Array2<f32>| -> Result<Array2<f32>> {
                if p.ncols() != 3 {
                    return Err(pkg_err(&file, format!("output `aot_probs` has {} columns, expected 3", p.ncols())));
                }
                let mut out = p.clone();
                for (k, c) in self.meta.aot_classes.iter().enumerate() {
                    out.column_mut((c + 1) as usize).assign(&p.column(k));
                }
                Ok(out)
            };
            Ok(match self.branches {
                Branches::DistAot => DirectionScores { distance: get1("distance")?, aot_probs: canonical(get2("aot_probs")?)? },
                Branches::AotOnly => {
                    let p = canonical(get2("aot_probs")?)?;
                    // No distance branch: rank by the probability of an effective move.
                    let d = p.index_axis(Axis(1), 0).to_owned() + p.index_axis(Axis(1), 2);
                    DirectionScores { distance: d, aot_probs: p }
                }
                Branches::SignedDist => {
                    let sd = get1("signed_distance")?;
                    // The sign is the arrow of time; a small |sd| means no effective change.
                    let still = self.meta.signed_distance_threshold;
                    let mut p = Array2::<f32>::zeros((sd.len(), 3));
                    for (i, v) in sd.iter().enumerate() {
                        let k = if v.abs() <= still { 1 } else if *v > 0.0 { 2 } else { 0 };
                        if let Some(x) = p.get_mut((i, k)) {
                            *x = 1.0;
                        }
                    }
                    DirectionScores { distance: sd.mapv(f32::abs), aot_probs: p }
                }
                Branches::Inverse => {
                    return Err(PolicyError::Input("an Inverse package scores no candidates".into()));
                }
                Branches::Binary => {
                    // No arrow of time: a likely success counts as "forward", so the
                    // model explores and never claims to move toward a goal.
                    let ps = get1("success_prob")?;
                    let mut p = Array2::<f32>::zeros((ps.len(), 3));
                    for (i, v) in ps.iter().enumerate() {
                        if let Some(x) = p.get_mut((i, if *v >= 0.5 { 2 } else { 1 })) {
                            *x = 1.0;
                        }
                    }
                    DirectionScores { distance: ps, aot_probs: p }
                }
            })
        })
    }

    /// The Inverse baseline: one unit direction per row of the embeddings.
    pub fn predict_direction(
        &self,
        dist_embedding: ArrayView2<'_, f32>,
        aot_embedding: ArrayView2<'_, f32>,
    ) -> Result<Array2<f32>> {
        if self.branches != Branches::Inverse {
            return Err(PolicyError::Input(format!(
                "{}: branches {:?} score candidate directions (decode); only an Inverse package predicts one",
                self.dir.display(),
                self.meta.branches
            )));
        }
        let n = dist_embedding.nrows();
        let e = self.meta.embedding;
        if dist_embedding.shape() != [n, e] || aot_embedding.shape() != [n, e] {
            return Err(PolicyError::Input(format!(
                "decoder inputs: embeddings {:?}/{:?}, expected [{n}, {e}]",
                dist_embedding.shape(),
                aot_embedding.shape()
            )));
        }
        self.with_sessions(|s| {
            let file = self.dir.join(&self.meta.files.direction_decoder);
            let er = |x: ort::Error| ort_err(&file, x);
            let (a, b) = (dist_embedding.as_standard_layout(), aot_embedding.as_standard_layout());
            let out = s
                .decoder
                .run(ort::inputs![
                    "dist_embedding" => TensorRef::from_array_view(a.view().into_dyn()).map_err(er)?,
                    "aot_embedding" => TensorRef::from_array_view(b.view().into_dyn()).map_err(er)?,
                ])
                .map_err(er)?;
            let name = self.decoder_outputs.first().map_or("", String::as_str);
            let a = output(&out, name, &file)?
                .try_extract_array::<f32>()
                .map_err(er)?
                .to_owned()
                .into_dimensionality()
                .map_err(|x| ort_err(&file, x))?;
            finite(a, &file, name)
        })
    }
}
