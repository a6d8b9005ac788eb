//! Change sets: what one commit changed, as plain data that a replica
//! context applies to reach the same scene, bit for bit. This is how a
//! distributed renderer keeps its workers in step while the application
//! only calls the API (Wald, Benthin & Slusallek 2003, section 5: the
//! application "knows nothing of the distributed rendering").
//!
//! A context records its changes once [`Context::record_changes`] is on;
//! [`Context::take_changes`] returns the set of the last commit, and
//! [`Context::apply_changes`] replays one on a replica and commits it.
//! Only what changed travels: new and redefined objects' geometry,
//! deletions, instance transforms, materials when one was added, new
//! textures, and the background SAH trees swapped in (rebuilt by the
//! replica from its own triangles, so that both use the same tree).

use std::collections::BTreeSet;
use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};
use openrt_accel::BuilderKind;
use serde::{Deserialize, Serialize};

use crate::context::{InstanceSlot, ObjectSlot, Promotion};
use crate::object::{ObjectMesh, ShadingData};
use crate::{Context, CoreError, Material, MaterialId, ObjectId, Texture, TextureId};

/// A material as plain data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialData {
    /// Ambient, diffuse, specular and emitted colours.
    pub colors: [[f32; 3]; 4],
    /// Shininess, transmission, index of refraction.
    pub params: [f32; 3],
    /// Texture index.
    pub texture: Option<u32>,
    /// Emission texture index.
    pub emission_texture: Option<u32>,
    /// One-sided surface.
    pub one_sided: bool,
}

/// A texture's full-size texels (the replica builds the mipmaps).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TextureData {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// 8-bit RGB texels, row by row, when every texel is exactly `k / 255`
    /// (textures loaded from 8-bit files): a quarter of the bytes.
    pub rgb8: Vec<u8>,
    /// RGB texels, row by row, otherwise.
    pub texels: Vec<[f32; 3]>,
    /// Addressing along u and v.
    pub wrap: [crate::TextureWrap; 2],
}

impl TextureData {
    fn of(t: &Texture) -> Self {
        let eight: Option<Vec<u8>> = t
            .texels()
            .iter()
            .flat_map(glam::Vec3A::to_array)
            .map(|c| {
                let b = (c * 255.0).round();
                ((0.0..=255.0).contains(&b) && f32::from(b as u8) / 255.0 == c).then_some(b as u8)
            })
            .collect();
        match eight {
            Some(rgb8) => Self {
                width: t.width() as u32,
                height: t.height() as u32,
                rgb8,
                texels: Vec::new(),
                wrap: t.wrap(),
            },
            None => Self {
                width: t.width() as u32,
                height: t.height() as u32,
                rgb8: Vec::new(),
                texels: t.texels().iter().map(glam::Vec3A::to_array).collect(),
                wrap: t.wrap(),
            },
        }
    }

    fn texture(&self) -> Option<Texture> {
        let texels: Vec<Vec3> = if self.rgb8.is_empty() {
            self.texels.iter().map(|c| Vec3::from_array(*c)).collect()
        } else {
            // The same arithmetic as loading an 8-bit file: bit-identical texels.
            self.rgb8
                .chunks_exact(3)
                .map(|p| Vec3::new(f32::from(p[0]), f32::from(p[1]), f32::from(p[2])) / 255.0)
                .collect()
        };
        Texture::new(self.width as usize, self.height as usize, texels).map(|t| t.with_wrap(self.wrap[0], self.wrap[1]))
    }
}

/// A finished object definition as plain data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeshData {
    /// Triangles.
    pub triangles: Vec<[[f32; 3]; 3]>,
    /// Vertex normals per triangle.
    pub normals: Vec<[[f32; 3]; 3]>,
    /// Whether each triangle had vertex normals.
    pub has_normals: Vec<bool>,
    /// Texture coordinates per triangle.
    pub uvs: Vec<[[f32; 2]; 3]>,
    /// Material index per triangle.
    pub materials: Vec<u32>,
    /// Degenerate triangles dropped from the definition.
    pub dropped: u64,
}

/// A change to an object slot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ObjectChange {
    /// Slot `index` (generation `generation`) got this definition.
    Defined {
        /// Slot.
        index: u32,
        /// Generation.
        generation: u32,
        /// The definition.
        mesh: MeshData,
        /// The builder of its tree: the replica builds the same tree.
        sah: bool,
        /// The object's own structure ([`Context::set_object_accel`]).
        accel: Option<crate::Accel>,
    },
    /// Slot `index` was deleted (its generation after the deletion).
    Deleted {
        /// Slot.
        index: u32,
        /// Generation after the deletion.
        generation: u32,
    },
    /// The background SAH tree of slot `index` was swapped in.
    Promoted {
        /// Slot.
        index: u32,
    },
}

/// A change to an instance slot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum InstanceChange {
    /// Slot `index` holds this instance.
    Set {
        /// Slot.
        index: u32,
        /// Generation.
        generation: u32,
        /// Its object's slot and generation.
        object: (u32, u32),
        /// Object to world, the 12 numbers of an affine matrix (column-major).
        transform: [f32; 12],
    },
    /// Slot `index` was removed (its generation after the removal).
    Removed {
        /// Slot.
        index: u32,
        /// Generation after the removal.
        generation: u32,
    },
}

impl ObjectChange {
    /// The slot changed.
    #[must_use]
    pub fn index(&self) -> u32 {
        match self {
            Self::Defined { index, .. } | Self::Deleted { index, .. } | Self::Promoted { index } => *index,
        }
    }
}

impl InstanceChange {
    /// The slot changed.
    #[must_use]
    pub fn index(&self) -> u32 {
        match self {
            Self::Set { index, .. } | Self::Removed { index, .. } => *index,
        }
    }
}

/// Most slots one change set may add beyond a replica's.
pub const MAX_SLOT_GROWTH: usize = 1 << 24;

/// What one commit changed.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ChangeSet {
    /// Frame number of the scene the commit made.
    pub frame: u64,
    /// The first set of a recording: it holds the whole scene, and a fresh
    /// replica takes its frame number from it.
    pub full: bool,
    /// The whole material table, when it changed.
    pub materials: Option<Vec<MaterialData>>,
    /// Textures added since the last set, in order.
    pub textures: Vec<TextureData>,
    /// Object changes, in slot order.
    pub objects: Vec<ObjectChange>,
    /// Instance changes, in slot order.
    pub instances: Vec<InstanceChange>,
    /// The master refits fast trees ([`Context::set_refit`]): the replica
    /// must too, to build the same trees.
    pub refit: bool,
    /// The master's object structure ([`Context::set_accel`]).
    pub accel: crate::Accel,
}

impl ChangeSet {
    /// The set as bytes (postcard).
    ///
    /// # Errors
    /// When serialisation fails (it does not for sets made here).
    pub fn to_bytes(&self) -> Result<Vec<u8>, String> {
        postcard::to_allocvec(self).map_err(|e| e.to_string())
    }

    /// A set from bytes.
    ///
    /// # Errors
    /// Malformed bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        postcard::from_bytes(bytes).map_err(|e| format!("malformed change set: {e}"))
    }
}

/// What a recording context has changed since its last commit.
#[derive(Default)]
pub(crate) struct ChangeLog {
    /// Instance slots set or removed.
    pub instances: BTreeSet<u32>,
    /// Object slots deleted.
    pub deleted: BTreeSet<u32>,
    /// Textures already sent.
    pub textures_sent: usize,
    /// No set was made yet.
    pub first: bool,
    /// The set of the last commit, until taken.
    pub ready: Option<ChangeSet>,
}

fn v3(v: Vec3) -> [f32; 3] {
    v.to_array()
}

fn mesh_data(m: &ObjectMesh) -> MeshData {
    MeshData {
        triangles: m.triangles.iter().map(|t| t.map(v3)).collect(),
        normals: m.shading.normals.iter().map(|n| n.map(v3)).collect(),
        has_normals: m.shading.has_normals.clone(),
        uvs: m.shading.uvs.iter().map(|uv| uv.map(|c| c.to_array())).collect(),
        materials: m.shading.materials.iter().map(|m| m.0).collect(),
        dropped: m.dropped as u64,
    }
}

fn mesh_from(d: &MeshData) -> Result<ObjectMesh, CoreError> {
    let n = d.triangles.len();
    if d.normals.len() != n || d.has_normals.len() != n || d.uvs.len() != n || d.materials.len() != n {
        return Err(CoreError::Changes {
            reason: format!("a mesh of {n} triangles has lists of other lengths"),
        });
    }
    Ok(ObjectMesh {
        triangles: d.triangles.iter().map(|t| t.map(Vec3::from_array)).collect(),
        shading: ShadingData {
            normals: d.normals.iter().map(|n| n.map(Vec3::from_array)).collect(),
            has_normals: d.has_normals.clone(),
            uvs: d.uvs.iter().map(|uv| uv.map(Vec2::from_array)).collect(),
            materials: d.materials.iter().map(|&m| MaterialId(m)).collect(),
        },
        dropped: usize::try_from(d.dropped).unwrap_or(usize::MAX),
    })
}

/// Object slot `index`, made (dead) if the context has fewer slots.
fn slot(objects: &mut Vec<ObjectSlot>, index: u32) -> &mut ObjectSlot {
    let i = index as usize;
    while objects.len() <= i {
        objects.push(ObjectSlot::dead());
    }
    &mut objects[i]
}

impl Context {
    /// Starts recording changes: from the next commit on, each commit
    /// leaves a [`ChangeSet`] for [`Context::take_changes`]. The first set
    /// holds everything committed so far.
    pub fn record_changes(&mut self) {
        let mut log = ChangeLog {
            first: true,
            ..ChangeLog::default()
        };
        log.instances.extend(0..self.instances.len() as u32);
        self.materials_dirty = true;
        // Committed objects are sent again as definitions.
        for slot in &mut self.objects {
            if slot.alive && slot.pending.is_none() {
                slot.resend = true;
            }
        }
        self.change_log = Some(log);
    }

    /// The change set of the last commit (`None` when not recording, or
    /// when it was taken already).
    pub fn take_changes(&mut self) -> Option<ChangeSet> {
        self.change_log.as_mut().and_then(|l| l.ready.take())
    }

    /// Records what the commit that just finished changed; called by
    /// `commit` before the pending definitions are installed.
    pub(crate) fn log_commit(&mut self, frame: u64, swapped: &[ObjectId]) {
        let Some(mut log) = self.change_log.take() else { return };
        let mut set = ChangeSet {
            frame,
            full: std::mem::take(&mut log.first),
            refit: self.refit,
            accel: self.accel,
            ..ChangeSet::default()
        };
        if self.materials_dirty {
            set.materials = Some(
                self.materials
                    .iter()
                    .map(|m| MaterialData {
                        colors: [v3(m.ambient), v3(m.diffuse), v3(m.specular), v3(m.emission)],
                        params: [m.shininess, m.transmission, m.ior],
                        texture: m.texture.map(|t| t.0),
                        emission_texture: m.emission_texture.map(|t| t.0),
                        one_sided: m.one_sided,
                    })
                    .collect(),
            );
        }
        for t in &self.textures[log.textures_sent..] {
            set.textures.push(TextureData::of(t));
        }
        log.textures_sent = self.textures.len();
        for (index, slot) in self.objects.iter_mut().enumerate() {
            let index = index as u32;
            if log.deleted.contains(&index) {
                set.objects.push(ObjectChange::Deleted {
                    index,
                    generation: slot.generation,
                });
            }
            if !slot.alive {
                continue;
            }
            let redefinition_sah = self.redefinition_builder == BuilderKind::Sah;
            let mesh = if let Some(p) = &slot.pending {
                // A rebuild for a new structure keeps the builder it had.
                let sah = match slot.forced_builder {
                    Some(b) => b == BuilderKind::Sah,
                    None => slot.geometry.is_none() || redefinition_sah,
                };
                Some((mesh_data(p), sah))
            } else if std::mem::take(&mut slot.resend) {
                slot.geometry.as_ref().map(|g| {
                    let sh = g.shading();
                    (
                        MeshData {
                            triangles: g.tree.triangles().iter().map(|t| t.map(v3)).collect(),
                            normals: sh.normals.iter().map(|n| n.map(v3)).collect(),
                            has_normals: sh.has_normals,
                            uvs: sh.uvs.iter().map(|uv| uv.map(|c| c.to_array())).collect(),
                            materials: sh.materials.iter().map(|m| m.0).collect(),
                            dropped: 0,
                        },
                        g.builder() == BuilderKind::Sah,
                    )
                })
            } else {
                None
            };
            if let Some((mesh, sah)) = mesh {
                set.objects.push(ObjectChange::Defined {
                    index,
                    generation: slot.generation,
                    mesh,
                    sah,
                    accel: slot.accel,
                });
            }
            if swapped.iter().any(|s| s.index == index) {
                set.objects.push(ObjectChange::Promoted { index });
            }
        }
        for &index in &log.instances {
            let Some(s) = self.instances.get(index as usize) else {
                continue;
            };
            set.instances.push(if s.alive {
                InstanceChange::Set {
                    index,
                    generation: s.generation,
                    object: (s.object.index, s.object.generation),
                    transform: s.transform.to_cols_array(),
                }
            } else {
                InstanceChange::Removed {
                    index,
                    generation: s.generation,
                }
            });
        }
        log.instances.clear();
        log.deleted.clear();
        log.ready = Some(set);
        self.change_log = Some(log);
    }

    /// Applies a change set made by another context and commits, so that
    /// this context's scene equals the other's after the same commit. A
    /// replica only applies sets: it makes no calls of its own, and
    /// builds no background trees (the sets say when to swap one in).
    ///
    /// # Errors
    /// [`CoreError::Changes`] for a set that does not fit this context (a
    /// frame out of order, an unknown slot), or the commit's own errors.
    pub fn apply_changes(&mut self, set: &ChangeSet) -> Result<crate::CommitStats, CoreError> {
        let bad = |reason: String| CoreError::Changes { reason };
        let fresh = self.frame == 0 && self.objects.is_empty() && self.instances.is_empty();
        if set.full && fresh && set.frame > 0 {
            self.frame = set.frame - 1;
        }
        if set.frame != self.frame + 1 {
            return Err(bad(format!(
                "change set for frame {} given to a replica at frame {}",
                set.frame, self.frame
            )));
        }
        self.ensure_not_defining("apply_changes")?;
        self.promote_after = None;
        self.refit = set.refit;
        self.accel = set.accel;
        if let Some(ms) = &set.materials {
            let mut table = Vec::with_capacity(ms.len());
            for m in ms {
                table.push(Material {
                    ambient: Vec3::from_array(m.colors[0]),
                    diffuse: Vec3::from_array(m.colors[1]),
                    specular: Vec3::from_array(m.colors[2]),
                    emission: Vec3::from_array(m.colors[3]),
                    shininess: m.params[0],
                    transmission: m.params[1],
                    ior: m.params[2],
                    texture: m.texture.map(TextureId),
                    emission_texture: m.emission_texture.map(TextureId),
                    one_sided: m.one_sided,
                });
            }
            self.materials = table;
            self.materials_dirty = true;
        }
        for t in &set.textures {
            let tex = t
                .texture()
                .ok_or_else(|| bad(format!("a {}x{} texture with bad texels", t.width, t.height)))?;
            self.create_texture(tex);
        }
        // A set names slots at most this far beyond the replica's (the
        // master allocates them one by one).
        let grows = |len: usize, index: u32| index as usize > len + MAX_SLOT_GROWTH;
        if let Some(i) = set
            .objects
            .iter()
            .map(ObjectChange::index)
            .find(|&i| grows(self.objects.len(), i))
        {
            return Err(bad(format!(
                "object slot {i} is far beyond this replica's {}",
                self.objects.len()
            )));
        }
        if let Some(i) = set
            .instances
            .iter()
            .map(InstanceChange::index)
            .find(|&i| grows(self.instances.len(), i))
        {
            return Err(bad(format!(
                "instance slot {i} is far beyond this replica's {}",
                self.instances.len()
            )));
        }
        for change in &set.objects {
            match change {
                ObjectChange::Defined {
                    index,
                    generation,
                    mesh,
                    sah,
                    accel,
                } => {
                    let s = slot(&mut self.objects, *index);
                    if !s.alive || s.generation != *generation {
                        *s = ObjectSlot {
                            generation: *generation,
                            ..ObjectSlot::dead()
                        };
                        s.alive = true;
                    }
                    s.pending = Some(mesh_from(mesh)?);
                    s.forced_builder = Some(if *sah { BuilderKind::Sah } else { BuilderKind::Fast });
                    s.accel = *accel;
                }
                ObjectChange::Deleted { index, generation } => {
                    let s = slot(&mut self.objects, *index);
                    *s = ObjectSlot {
                        generation: *generation,
                        ..ObjectSlot::dead()
                    };
                }
                ObjectChange::Promoted { index } => {
                    let s = slot(&mut self.objects, *index);
                    let geom = s
                        .geometry
                        .as_ref()
                        .ok_or_else(|| bad(format!("object slot {index} promoted before it was defined")))?;
                    let tree = crate::object::ObjectTree::build(
                        crate::Accel::Kd,
                        geom.tree.triangles().to_vec(),
                        openrt_accel::BuilderKind::Sah,
                        None,
                    )
                    .map_err(|source| CoreError::Accel {
                        call: "apply_changes",
                        source,
                    })?;
                    s.promotion = Some(Promotion::Ready {
                        version: s.version,
                        result: Ok(Arc::new(geom.with_tree(tree))),
                    });
                }
            }
        }
        for change in &set.instances {
            let (index, slot) = match change {
                InstanceChange::Set {
                    index,
                    generation,
                    object,
                    transform,
                } => (
                    *index,
                    InstanceSlot {
                        generation: *generation,
                        alive: true,
                        object: ObjectId {
                            index: object.0,
                            generation: object.1,
                        },
                        transform: Affine3A::from_cols_array(transform),
                    },
                ),
                InstanceChange::Removed { index, generation } => (
                    *index,
                    InstanceSlot {
                        generation: *generation,
                        alive: false,
                        object: ObjectId {
                            index: 0,
                            generation: 0,
                        },
                        transform: Affine3A::IDENTITY,
                    },
                ),
            };
            let i = index as usize;
            while self.instances.len() <= i {
                self.instances.push(InstanceSlot {
                    generation: 0,
                    alive: false,
                    object: ObjectId {
                        index: 0,
                        generation: 0,
                    },
                    transform: Affine3A::IDENTITY,
                });
            }
            self.instances[i] = slot;
        }
        self.commit()
    }
}

#[cfg(test)]
mod tests {
    use glam::{Mat4, Vec3};
    use openrt_accel::{BuilderKind, Ray, meshgen};

    use crate::{ChangeSet, Context, PrimitiveKind};

    fn define(ctx: &mut Context, id: crate::ObjectId, seed: u64) {
        ctx.begin_object(id).unwrap();
        ctx.begin(PrimitiveKind::Triangles).unwrap();
        for t in meshgen::bumpy_sphere(300, seed, 0.2) {
            for v in t {
                ctx.vertex(v).unwrap();
            }
        }
        ctx.end().unwrap();
        ctx.end_object().unwrap();
    }

    /// Sends the last commit's set through bytes and checks the replica.
    fn sync(master: &mut Context, replica: &mut Context) -> ChangeSet {
        let set = master.take_changes().unwrap();
        let set = ChangeSet::from_bytes(&set.to_bytes().unwrap()).unwrap();
        replica.apply_changes(&set).unwrap();
        let (a, b) = (master.scene(), replica.scene());
        assert_eq!(a.frame(), b.frame());
        assert_eq!(a.instances().len(), b.instances().len());
        for (x, y) in a.instances().iter().zip(b.instances()) {
            assert_eq!((x.id, x.object, x.to_world), (y.id, y.object, y.to_world));
            assert_eq!(x.geometry.builder(), y.geometry.builder());
            match (&x.geometry.tree, &y.geometry.tree) {
                (crate::ObjectTree::Kd(p), crate::ObjectTree::Kd(q)) => {
                    assert_eq!(p.nodes(), q.nodes(), "the same tree");
                }
                (crate::ObjectTree::Bvh(p, _), crate::ObjectTree::Bvh(q, _)) => {
                    assert_eq!(p.stats().sah_cost, q.stats().sah_cost, "the same tree");
                }
                _ => panic!("different structures"),
            }
        }
        for r in meshgen::random_rays(300, 9, openrt_accel::Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0))) {
            assert_eq!(a.intersect(&r), b.intersect(&r));
        }
        let _ = Ray::infinite(Vec3::ZERO, Vec3::X);
        set
    }

    #[test]
    fn promotions_deletions_and_removals_reach_the_replica() {
        let mut m = Context::new();
        // Promotions replace a kd-tree's fast build (a BVH has one builder).
        m.set_accel(crate::Accel::Kd);
        m.set_promote_after(Some(1));
        let (a, b) = (m.gen_object(), m.gen_object());
        define(&mut m, a, 1);
        define(&mut m, b, 2);
        m.instantiate(a).unwrap();
        m.load_matrix(Mat4::from_translation(Vec3::X * 2.0)).unwrap();
        let ib = m.instantiate(b).unwrap();
        m.commit().unwrap();
        // Recording starts after a commit: the first set holds everything.
        m.record_changes();
        let mut r = Context::new();
        r.set_accel(crate::Accel::Kd);
        define(&mut m, a, 3); // redefined: a fast tree
        let first = {
            m.commit().unwrap();
            sync(&mut m, &mut r)
        };
        assert!(first.full && first.objects.len() == 2 && first.instances.len() == 2);
        // Unchanged: the background SAH build starts, then is swapped in.
        m.commit().unwrap();
        sync(&mut m, &mut r);
        m.wait_for_promotions();
        let stats = m.commit().unwrap();
        assert_eq!(stats.promotions_swapped, vec![a]);
        let set = sync(&mut m, &mut r);
        assert_eq!(set.objects, vec![super::ObjectChange::Promoted { index: a.index() }]);
        assert_eq!(
            r.object_builder(crate::ObjectId { ..a }).unwrap(),
            Some(BuilderKind::Sah)
        );
        // A moved instance sends only its transform.
        m.set_instance_transform(ib, Mat4::from_translation(Vec3::Y)).unwrap();
        m.commit().unwrap();
        let set = sync(&mut m, &mut r);
        assert!(set.objects.is_empty() && set.instances.len() == 1 && set.materials.is_none());
        assert!(
            set.to_bytes().unwrap().len() < 80,
            "{} bytes",
            set.to_bytes().unwrap().len()
        );
        // Removal and deletion.
        m.remove_instance(ib).unwrap();
        m.delete_object(b).unwrap();
        m.commit().unwrap();
        sync(&mut m, &mut r);
        assert!(r.object_builder(b).is_err(), "deleted on the replica too");
    }

    #[test]
    fn textures_reach_the_replica_with_their_wrap_modes_and_emission_textures() {
        use crate::{Texture, TextureWrap};
        let mut m = Context::new();
        let a = m.gen_object();
        define(&mut m, a, 1);
        m.instantiate(a).unwrap();
        m.commit().unwrap();
        m.record_changes();
        let mut r = Context::new();
        let texels = (0..6).map(|i| Vec3::splat(i as f32 / 7.0)).collect();
        let t = Texture::new(3, 2, texels)
            .unwrap()
            .with_wrap(TextureWrap::MirroredRepeat, TextureWrap::ClampToEdge);
        let id = m.create_texture(t.clone());
        m.create_material(crate::Material {
            emission_texture: Some(id),
            ..crate::Material::default()
        })
        .unwrap();
        m.commit().unwrap();
        sync(&mut m, &mut r);
        assert_eq!(*r.scene().textures()[0], t, "texels and wrap modes");
        assert_eq!(r.scene().materials(), m.scene().materials(), "the emission texture too");
    }

    #[test]
    fn structures_and_their_switches_reach_the_replica() {
        let mut m = Context::new();
        let (a, b) = (m.gen_object(), m.gen_object());
        define(&mut m, a, 1);
        define(&mut m, b, 2);
        m.instantiate(a).unwrap();
        m.load_matrix(Mat4::from_translation(Vec3::X * 2.0)).unwrap();
        m.instantiate(b).unwrap();
        m.commit().unwrap();
        m.record_changes();
        let mut r = Context::new();
        m.commit().unwrap();
        sync(&mut m, &mut r);
        // BVHs for the scene, but a kd-tree for `b`: both objects are
        // rebuilt with the builders they had (SAH), and so are the replica's.
        m.set_accel(crate::Accel::Bvh);
        m.set_object_accel(b, Some(crate::Accel::Kd)).unwrap();
        m.commit().unwrap();
        sync(&mut m, &mut r);
        for ctx in [&m, &r] {
            let accels: Vec<crate::Accel> = ctx
                .scene()
                .instances()
                .iter()
                .map(|i| i.geometry.tree.accel())
                .collect();
            assert_eq!(accels, vec![crate::Accel::Bvh, crate::Accel::Kd]);
            assert_eq!(ctx.object_builder(a).unwrap(), Some(BuilderKind::Sah));
            assert_eq!(ctx.object_builder(b).unwrap(), Some(BuilderKind::Sah));
        }
        // Back to the context's structure.
        m.set_object_accel(b, None).unwrap();
        m.commit().unwrap();
        sync(&mut m, &mut r);
        assert!(
            r.scene()
                .instances()
                .iter()
                .all(|i| i.geometry.tree.accel() == crate::Accel::Bvh)
        );
        assert!(matches!(m.set_object_accel(crate::ObjectId { ..a }, None), Ok(())));
        m.delete_object(a).unwrap();
        assert!(m.set_object_accel(a, None).is_err(), "a deleted object is refused");
    }
}
