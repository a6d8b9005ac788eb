//! The OpenRT-style immediate API.

use std::sync::Arc;

use glam::{Affine3A, Mat3, Mat4, Vec2, Vec3};
use openrt_accel::{Triangle, is_valid_triangle};

use crate::instance::check_transform;
use crate::limits::{MAX_COORDINATE, within_coordinate_limit};
use crate::matrix_stack::MatrixStack;
use crate::object::{ObjectGeometry, ObjectMesh};
use crate::{CoreError, InstanceId, Material, MaterialId, ObjectId, PrimitiveKind, Scene, Texture, TextureId};

/// A background SAH build of an object that stopped changing, for geometry
/// `version`; the build yields the object's new geometry or why it failed.
pub(crate) enum Promotion {
    Running {
        version: u64,
        /// The build's answer, sent by the pool thread that ran it.
        result: crossbeam::channel::Receiver<Result<Arc<ObjectGeometry>, String>>,
    },
    Ready {
        version: u64,
        result: Result<Arc<ObjectGeometry>, String>,
    },
    /// Reported once by a commit; not retried for this version.
    Failed { version: u64, reason: String },
}

impl Promotion {
    /// Waits for a running build (if needed) and returns it as ready.
    pub(crate) fn finish(self) -> Self {
        match self {
            Self::Running { version, result } => Self::Ready {
                version,
                result: result
                    .recv()
                    .unwrap_or_else(|_| Err("the background build panicked".into())),
            },
            done => done,
        }
    }
}

pub(crate) struct ObjectSlot {
    pub generation: u32,
    pub alive: bool,
    /// A finished definition waiting for commit.
    pub pending: Option<ObjectMesh>,
    /// The committed geometry.
    pub geometry: Option<Arc<ObjectGeometry>>,
    /// Increments with each committed definition.
    pub version: u64,
    /// Commits since the geometry last changed.
    pub unchanged_commits: u32,
    pub promotion: Option<Promotion>,
    /// Recording changes: send the committed geometry in the next set.
    pub resend: bool,
    /// A replica builds the pending definition with the master's builder.
    pub forced_builder: Option<openrt_accel::BuilderKind>,
    /// This object's structure, over the context's ([`Context::set_object_accel`]).
    pub accel: Option<crate::Accel>,
}

impl ObjectSlot {
    /// Queues the committed geometry for a rebuild with the builder it had
    /// when its tree is not of structure `accel` (nothing for a dead slot,
    /// one without geometry, or one with a pending definition, which the
    /// next commit builds with the new structure anyway).
    pub(crate) fn requeue_for(&mut self, accel: crate::Accel) {
        if !self.alive || self.pending.is_some() {
            return;
        }
        if let Some(g) = self.geometry.as_ref().filter(|g| g.tree.accel() != accel) {
            self.forced_builder = Some(g.builder());
            self.pending = Some(crate::ObjectMesh {
                triangles: g.tree.triangles().to_vec(),
                shading: g.shading(),
                dropped: 0,
            });
        }
    }

    /// A slot with nothing in it.
    pub(crate) fn dead() -> Self {
        Self {
            generation: 0,
            alive: false,
            pending: None,
            geometry: None,
            version: 0,
            unchanged_commits: 0,
            promotion: None,
            resend: false,
            forced_builder: None,
            accel: None,
        }
    }
}

pub(crate) struct InstanceSlot {
    pub generation: u32,
    pub alive: bool,
    pub object: ObjectId,
    pub transform: Affine3A,
}

struct Vertex {
    p: Vec3,
    n: Option<Vec3>,
    uv: Option<Vec2>,
}

/// The arrays of [`Context::draw_elements`]: one position per vertex, and
/// optionally one normal and one texture coordinate per vertex.
#[derive(Clone, Copy, Debug, Default)]
pub struct VertexArrays<'a> {
    /// Positions (object space of the current matrix).
    pub positions: &'a [Vec3],
    /// Normals, one per position.
    pub normals: Option<&'a [Vec3]>,
    /// Texture coordinates, one per position.
    pub uvs: Option<&'a [Vec2]>,
}

/// Appends the valid triangles among `tris` (corners numbered for
/// `vertex`) to `mesh` with `material`; zero-area ones are counted as dropped.
fn emit_triangles<'v>(
    mesh: &mut ObjectMesh,
    material: MaterialId,
    tris: &[[usize; 3]],
    vertex: impl Fn(usize) -> &'v Vertex,
) {
    // PERF: room for every triangle up front: grown push by push, a
    // 100k-triangle redefinition spent a third of its time in reallocations.
    let sh = &mut mesh.shading;
    sh.has_normals.reserve(tris.len());
    sh.normals.reserve(tris.len());
    sh.uvs.reserve(tris.len());
    sh.materials.reserve(tris.len());
    mesh.triangles.reserve(tris.len());
    for &[a, b, c] in tris {
        let (va, vb, vc) = (vertex(a), vertex(b), vertex(c));
        let tri: Triangle = [va.p, vb.p, vc.p];
        if !is_valid_triangle(&tri) {
            mesh.dropped += 1;
            continue;
        }
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let normals = match (va.n, vb.n, vc.n) {
            (Some(x), Some(y), Some(z)) => Some([x, y, z]),
            _ => None,
        };
        let sh = &mut mesh.shading;
        sh.has_normals.push(normals.is_some());
        sh.normals.push(normals.unwrap_or([ng; 3]));
        sh.uvs.push([
            va.uv.unwrap_or_default(),
            vb.uv.unwrap_or_default(),
            vc.uv.unwrap_or_default(),
        ]);
        sh.materials.push(material);
        mesh.triangles.push(tri);
    }
}

/// An open object definition and the state it saved.
struct Definition {
    id: ObjectId,
    saved_stack: MatrixStack,
    saved_material: MaterialId,
    primitive: Option<PrimitiveKind>,
    vertices: Vec<Vertex>,
    normal: Option<Vec3>,
    uv: Option<Vec2>,
    mesh: ObjectMesh,
}

/// The OpenRT-style context: objects, instances, a matrix stack and
/// materials, committed into immutable [`Scene`] frames.
///
/// Semantics (after OpenRT and OpenGL display lists):
/// - `begin_object(id)` opens a definition of `id`; the matrix stack starts
///   from the identity inside it, and the matrix stack and current material
///   are restored by `end_object`: nothing set inside a definition leaks out.
/// - Vertices and normals are transformed by the current matrix when they
///   are emitted (so `push/translate/pop` inside a definition build the
///   object from parts).
/// - Beginning a defined object again redefines it: its geometry is replaced
///   at the next commit; no other object changes.
/// - `instantiate(id)` places the object with the current matrix.
/// - Every misuse returns a [`CoreError`] naming the call; a failing call
///   changes nothing.
// NOTE: its flags are independent (two dirty bits, a setting, a test hook),
// not the states of one machine.
#[allow(clippy::struct_excessive_bools)]
pub struct Context {
    pub(crate) objects: Vec<ObjectSlot>,
    free_objects: Vec<u32>,
    pub(crate) instances: Vec<InstanceSlot>,
    free_instances: Vec<u32>,
    matrices: MatrixStack,
    def: Option<Definition>,
    pub(crate) materials: Vec<Material>,
    pub(crate) materials_dirty: bool,
    pub(crate) textures: Vec<Arc<Texture>>,
    pub(crate) textures_dirty: bool,
    current_material: MaterialId,
    pub(crate) frame: u64,
    pub(crate) scene: Arc<Scene>,
    pub(crate) promote_after: Option<u32>,
    pub(crate) redefinition_builder: openrt_accel::BuilderKind,
    /// Redefined objects whose tree came from the fast builder are refitted
    /// ([`Context::set_refit`]).
    pub(crate) refit: bool,
    /// The structure new and redefined objects get ([`Context::set_accel`]).
    pub(crate) accel: crate::Accel,
    /// The structure over the instances ([`Context::set_top_level`]).
    pub(crate) top_level: crate::TopLevel,
    /// The pool of the commit, the background builds and the renderers
    /// given it ([`Context::pool`]); `None` only when no thread could be
    /// started (the commit then runs on the calling thread).
    pool: Option<crate::ThreadPool>,
    /// Keeps the top-level build's scratch memory from frame to frame; runs
    /// on `pool`.
    pub(crate) bsp_builder: openrt_accel::BspBuilder,
    /// Record buffers of dropped large objects, for the next commits.
    pub(crate) record_bin: Arc<crate::shading_record::RecordBin>,
    /// Failures injected by the unit tests (absent from other builds).
    #[cfg(test)]
    pub(crate) hooks: TestHooks,
    /// What changed since the last commit, when recording ([`Context::record_changes`]).
    pub(crate) change_log: Option<crate::changes::ChangeLog>,
}

impl Default for Context {
    fn default() -> Self {
        Self::new()
    }
}

impl Context {
    /// An empty context with the default material.
    #[must_use]
    pub fn new() -> Self {
        let pool = crate::ThreadPool::all_cores().ok();
        let bsp_builder = pool.as_ref().map_or_else(
            || openrt_accel::BspBuilder::new(1),
            |p| openrt_accel::BspBuilder::with_pool(std::sync::Arc::clone(p.rayon())),
        );
        Self {
            objects: Vec::new(),
            free_objects: Vec::new(),
            instances: Vec::new(),
            free_instances: Vec::new(),
            matrices: MatrixStack::default(),
            def: None,
            materials: vec![Material::default()],
            materials_dirty: true,
            textures: Vec::new(),
            textures_dirty: true,
            current_material: MaterialId::DEFAULT,
            frame: 0,
            scene: Arc::new(Scene::default()),
            promote_after: Some(3),
            redefinition_builder: openrt_accel::BuilderKind::Fast,
            refit: true,
            accel: crate::Accel::default(),
            top_level: crate::TopLevel::default(),
            pool,
            bsp_builder,
            record_bin: Arc::default(),
            #[cfg(test)]
            hooks: TestHooks::default(),
            change_log: None,
        }
    }

    /// Commits without change after which an object rebuilt with the fast
    /// builder gets an SAH tree built in the background (`None`: never).
    pub fn set_promote_after(&mut self, commits: Option<u32>) {
        self.promote_after = commits;
    }

    /// The builder for redefined objects: [`BuilderKind::Fast`](openrt_accel::BuilderKind::Fast)
    /// (the paper's choice for unstructured motion, the default) or SAH (to
    /// measure the trade-off).
    pub fn set_redefinition_builder(&mut self, builder: openrt_accel::BuilderKind) {
        self.redefinition_builder = builder;
    }

    /// Whether a redefined object whose last tree came from the fast
    /// builder gets that tree's split planes with its new triangles
    /// ([`KdTree::refit_fast`](openrt_accel::KdTree::refit_fast): rebuilt
    /// afresh when its SAH cost grows past
    /// [`DEFAULT_REFIT_COST_LIMIT`](openrt_accel::DEFAULT_REFIT_COST_LIMIT)
    /// times the last full build's) rather than a tree built afresh.
    /// Default: on. Trees, and so the images, then depend on the frames
    /// committed before, not on the thread count.
    pub fn set_refit(&mut self, refit: bool) {
        self.refit = refit;
    }

    /// The structure built over objects: BVHs (the default) or kd-trees.
    /// Objects already built are rebuilt with the new structure at the
    /// next commit (each with the builder it had); the images are the same
    /// bytes either way.
    pub fn set_accel(&mut self, accel: crate::Accel) {
        if accel == self.accel {
            return;
        }
        self.accel = accel;
        for slot in &mut self.objects {
            if slot.accel.is_none() {
                slot.requeue_for(accel);
            }
        }
    }

    /// The structure of one object, over the context's (`None`: the
    /// context's, [`Context::set_accel`]); a built object is rebuilt with it
    /// at the next commit. The images are the same bytes either way.
    pub fn set_object_accel(&mut self, id: ObjectId, accel: Option<crate::Accel>) -> Result<(), CoreError> {
        self.object_slot("set_object_accel", id)?;
        let want = accel.unwrap_or(self.accel);
        let slot = &mut self.objects[id.index as usize];
        slot.accel = accel;
        slot.requeue_for(want);
        Ok(())
    }

    /// The structure new and redefined objects get.
    #[must_use]
    pub fn accel(&self) -> crate::Accel {
        self.accel
    }

    /// The structure over the instances' world boxes from the next commit
    /// on: the paper's BSP, a BVH, or (the default) the BSP up to
    /// [`TOP_LEVEL_BVH_MIN`](crate::TOP_LEVEL_BVH_MIN) instances and a BVH
    /// from there. The images are the same bytes either way.
    pub fn set_top_level(&mut self, top_level: crate::TopLevel) {
        self.top_level = top_level;
    }

    /// The top-level choice ([`Context::set_top_level`]).
    #[must_use]
    pub fn top_level(&self) -> crate::TopLevel {
        self.top_level
    }

    /// Gives the context a new pool of `threads` threads
    /// ([`Context::set_pool`]; default: one per core). Trees do not depend
    /// on it.
    ///
    /// # Errors
    /// As [`ThreadPool::new`](crate::ThreadPool::new).
    pub fn set_threads(&mut self, threads: usize) -> Result<(), CoreError> {
        crate::check_threads("set_threads", threads)?;
        self.set_pool(&crate::ThreadPool::new(threads)?);
        Ok(())
    }

    /// Runs the commit (the top-level build, the fast builds of redefined
    /// objects, new instance records) and the background SAH builds on
    /// `pool`; give the same pool to the renderer
    /// ([`Renderer::with_pool`](crate::Renderer::with_pool)) so that one
    /// set of threads does everything.
    pub fn set_pool(&mut self, pool: &crate::ThreadPool) {
        self.bsp_builder = openrt_accel::BspBuilder::with_pool(Arc::clone(pool.rayon()));
        self.pool = Some(pool.clone());
    }

    /// The context's pool, for a renderer to share
    /// ([`Renderer::with_pool`](crate::Renderer::with_pool)).
    ///
    /// # Errors
    /// [`CoreError::RenderThread`] when no pool could be started.
    pub fn pool(&mut self) -> Result<crate::ThreadPool, CoreError> {
        if let Some(p) = &self.pool {
            return Ok(p.clone());
        }
        let p = crate::ThreadPool::all_cores()?;
        self.set_pool(&p);
        Ok(p)
    }

    /// The scene of the last commit.
    #[must_use]
    pub fn scene(&self) -> Arc<Scene> {
        Arc::clone(&self.scene)
    }

    // ----- objects -------------------------------------------------------

    /// A new object id (like `glGenLists`); the object has no geometry until defined.
    pub fn gen_object(&mut self) -> ObjectId {
        let fresh = ObjectSlot {
            alive: true,
            ..ObjectSlot::dead()
        };
        if let Some(i) = self.free_objects.pop() {
            let slot = &mut self.objects[i as usize];
            let generation = slot.generation;
            *slot = ObjectSlot { generation, ..fresh };
            ObjectId { index: i, generation }
        } else {
            self.objects.push(fresh);
            ObjectId {
                index: (self.objects.len() - 1) as u32,
                generation: 0,
            }
        }
    }

    pub(crate) fn object_slot(&self, call: &'static str, id: ObjectId) -> Result<&ObjectSlot, CoreError> {
        match self.objects.get(id.index as usize) {
            Some(s) if s.alive && s.generation == id.generation => Ok(s),
            _ => Err(CoreError::UnknownObject { call, id }),
        }
    }

    fn no_definition(&self, call: &'static str) -> Result<(), CoreError> {
        match &self.def {
            Some(d) => Err(CoreError::InsideObject { call, object: d.id }),
            None => Ok(()),
        }
    }

    /// Opens the definition (or redefinition) of `id`.
    pub fn begin_object(&mut self, id: ObjectId) -> Result<(), CoreError> {
        if let Some(d) = &self.def {
            return Err(CoreError::NestedObject {
                object: id,
                current: d.id,
            });
        }
        self.object_slot("begin_object", id)?;
        self.def = Some(Definition {
            id,
            saved_stack: std::mem::take(&mut self.matrices),
            saved_material: self.current_material,
            primitive: None,
            vertices: Vec::new(),
            normal: None,
            uv: None,
            mesh: ObjectMesh::default(),
        });
        Ok(())
    }

    /// Closes the open definition; its geometry replaces the object's at the next commit.
    /// Returns the number of degenerate triangles that were dropped.
    pub fn end_object(&mut self) -> Result<usize, CoreError> {
        let Some(d) = &self.def else {
            return Err(CoreError::NotInObject { call: "end_object" });
        };
        if let Some(p) = d.primitive {
            return Err(CoreError::PrimitiveOpen {
                call: "end_object",
                current: p,
            });
        }
        let d = self.def.take().expect("checked above");
        self.matrices = d.saved_stack;
        self.current_material = d.saved_material;
        let dropped = d.mesh.dropped;
        let slot = &mut self.objects[d.id.index as usize];
        slot.pending = Some(d.mesh);
        Ok(dropped)
    }

    /// Abandons the open definition: the object keeps its previous
    /// definition (or stays undefined), and the matrix stack and current
    /// material are restored as `end_object` would. Use it when a
    /// definition cannot be completed; [`Context::define_object`] does it
    /// for you.
    pub fn abort_object(&mut self) -> Result<ObjectId, CoreError> {
        let Some(d) = self.def.take() else {
            return Err(CoreError::NotInObject { call: "abort_object" });
        };
        self.matrices = d.saved_stack;
        self.current_material = d.saved_material;
        Ok(d.id)
    }

    /// Defines `id` with the calls made by `body` between `begin_object`
    /// and `end_object`; if `body` or `end_object` fails, the definition is
    /// aborted ([`Context::abort_object`]) and the context is as before the
    /// call. Returns the number of degenerate triangles dropped.
    pub fn define_object<E: From<CoreError>>(
        &mut self,
        id: ObjectId,
        body: impl FnOnce(&mut Self) -> Result<(), E>,
    ) -> Result<usize, E> {
        self.begin_object(id)?;
        let done = body(self).and_then(|()| self.end_object().map_err(E::from));
        if done.is_err() && self.def.as_ref().is_some_and(|d| d.id == id) {
            let _ = self.abort_object();
        }
        done
    }

    /// Deletes an object. Its id becomes stale; instances still referring to
    /// it make the next commit fail until they are removed.
    pub fn delete_object(&mut self, id: ObjectId) -> Result<(), CoreError> {
        if let Some(d) = &self.def
            && d.id == id
        {
            return Err(CoreError::InsideObject {
                call: "delete_object",
                object: id,
            });
        }
        self.object_slot("delete_object", id)?;
        if let Some(log) = &mut self.change_log {
            log.deleted.insert(id.index);
        }
        let slot = &mut self.objects[id.index as usize];
        slot.alive = false;
        slot.pending = None;
        slot.geometry = None;
        slot.promotion = None;
        // A slot whose generation would wrap is retired, so that no handle
        // is ever issued twice.
        if let Some(g) = slot.generation.checked_add(1) {
            slot.generation = g;
            self.free_objects.push(id.index);
        }
        Ok(())
    }

    // ----- primitives ----------------------------------------------------

    fn def_mut(&mut self, call: &'static str) -> Result<&mut Definition, CoreError> {
        self.def.as_mut().ok_or(CoreError::NotInObject { call })
    }

    /// Starts a primitive.
    pub fn begin(&mut self, kind: PrimitiveKind) -> Result<(), CoreError> {
        let d = self.def_mut("begin")?;
        if let Some(p) = d.primitive {
            return Err(CoreError::PrimitiveOpen {
                call: "begin",
                current: p,
            });
        }
        d.primitive = Some(kind);
        d.vertices.clear();
        Ok(())
    }

    /// Ends the primitive: its vertices become triangles of the object.
    /// Zero-area triangles are dropped and counted.
    pub fn end(&mut self) -> Result<(), CoreError> {
        let material = self.current_material;
        let d = self.def_mut("end")?;
        let Some(kind) = d.primitive else {
            return Err(CoreError::NotInPrimitive { call: "end" });
        };
        let tris = kind.triangulate(d.vertices.len())?;
        d.primitive = None;
        let vertices = std::mem::take(&mut d.vertices);
        emit_triangles(&mut d.mesh, material, &tris, |k| &vertices[k]);
        d.vertices = vertices;
        d.vertices.clear();
        Ok(())
    }

    /// A whole primitive from vertex arrays, like OpenGL's `glDrawElements`
    /// over vertex, normal and texture coordinate arrays: the same triangles
    /// as `begin(kind)`, then for each index its `normal`, `tex_coord` and
    /// `vertex`, then `end()`, with positions under the current matrix and
    /// normals under its inverse transpose (computed once, not per vertex).
    /// A zero normal counts as none (its triangle is shaded with the
    /// geometric normal); without `uvs` the coordinates are (0, 0).
    ///
    /// # Errors
    /// As those calls (`NotInObject`, `PrimitiveOpen`, `NonFinite`,
    /// `CoordinateLimit`, `IncompletePrimitive`), and
    /// [`CoreError::VertexIndex`] / [`CoreError::ArrayLength`] for an
    /// index beyond the arrays or arrays of different lengths; on an error
    /// nothing of the primitive is added.
    pub fn draw_elements(
        &mut self,
        kind: PrimitiveKind,
        arrays: &VertexArrays<'_>,
        indices: &[u32],
    ) -> Result<(), CoreError> {
        const CALL: &str = "draw_elements";
        let material = self.current_material;
        let m = self.matrices.top();
        let d = self.def_mut(CALL)?;
        if let Some(p) = d.primitive {
            return Err(CoreError::PrimitiveOpen { call: CALL, current: p });
        }
        let n = arrays.positions.len();
        for (what, len) in [
            ("normal", arrays.normals.map(<[Vec3]>::len)),
            ("texture coordinate", arrays.uvs.map(<[Vec2]>::len)),
        ] {
            if let Some(len) = len.filter(|&l| l != n) {
                return Err(CoreError::ArrayLength {
                    call: CALL,
                    what,
                    len,
                    vertices: n,
                });
            }
        }
        if let Some((at, &index)) = indices.iter().enumerate().find(|(_, i)| **i as usize >= n) {
            return Err(CoreError::VertexIndex {
                call: CALL,
                index,
                at,
                vertices: n,
            });
        }
        let tris = kind.triangulate(indices.len())?;
        let nm = Mat3::from_mat4(m).inverse().transpose();
        let mut vertices = Vec::with_capacity(n);
        for (i, &p) in arrays.positions.iter().enumerate() {
            let wp = m.transform_point3(p);
            if !p.is_finite() || !wp.is_finite() {
                return Err(CoreError::NonFinite {
                    call: CALL,
                    what: format!("position {i} ({p}, transformed {wp})"),
                });
            }
            if !within_coordinate_limit(wp) {
                return Err(CoreError::CoordinateLimit {
                    call: CALL,
                    what: format!("position {i}"),
                    value: f64::from(wp.abs().max_element()),
                    limit: f64::from(MAX_COORDINATE),
                });
            }
            let normal = arrays.normals.map(|ns| ns[i]);
            if let Some(v) = normal.filter(|v| !v.is_finite()) {
                return Err(CoreError::NonFinite {
                    call: CALL,
                    what: format!("normal {i} ({v})"),
                });
            }
            let uv = arrays.uvs.map(|t| t[i]);
            if let Some(t) = uv.filter(|t| !t.is_finite()) {
                return Err(CoreError::NonFinite {
                    call: CALL,
                    what: format!("texture coordinate {i} ({t})"),
                });
            }
            let n = normal.filter(|v| *v != Vec3::ZERO).and_then(|v| {
                let w = nm * v;
                w.is_finite().then_some(w)
            });
            vertices.push(Vertex { p: wp, n, uv });
        }
        emit_triangles(&mut d.mesh, material, &tris, |k| &vertices[indices[k] as usize]);
        Ok(())
    }

    /// Emits a vertex (transformed by the current matrix) with the current
    /// normal and texture coordinate.
    pub fn vertex(&mut self, p: Vec3) -> Result<(), CoreError> {
        if !p.is_finite() {
            return Err(CoreError::NonFinite {
                call: "vertex",
                what: format!("position {p}"),
            });
        }
        let m = self.matrices.top();
        let d = self.def_mut("vertex")?;
        if d.primitive.is_none() {
            return Err(CoreError::NotInPrimitive { call: "vertex" });
        }
        let n = d.normal.and_then(|n| {
            let nm = Mat3::from_mat4(m).inverse().transpose();
            let w = nm * n;
            w.is_finite().then_some(w)
        });
        let (uv, wp) = (d.uv, m.transform_point3(p));
        if !wp.is_finite() {
            return Err(CoreError::NonFinite {
                call: "vertex",
                what: format!("transformed position {wp}"),
            });
        }
        if !within_coordinate_limit(wp) {
            return Err(CoreError::CoordinateLimit {
                call: "vertex",
                what: format!("position {wp}"),
                value: f64::from(wp.abs().max_element()),
                limit: f64::from(MAX_COORDINATE),
            });
        }
        d.vertices.push(Vertex { p: wp, n, uv });
        Ok(())
    }

    /// Sets the current normal (object space of the current matrix).
    pub fn normal(&mut self, n: Vec3) -> Result<(), CoreError> {
        if !n.is_finite() {
            return Err(CoreError::NonFinite {
                call: "normal",
                what: format!("normal {n}"),
            });
        }
        self.def_mut("normal")?.normal = Some(n);
        Ok(())
    }

    /// Clears the current normal: following vertices have none, and their
    /// triangles are shaded with the geometric normal.
    pub fn clear_normal(&mut self) -> Result<(), CoreError> {
        self.def_mut("clear_normal")?.normal = None;
        Ok(())
    }

    /// Clears the current texture coordinate (following vertices get (0, 0)).
    pub fn clear_tex_coord(&mut self) -> Result<(), CoreError> {
        self.def_mut("clear_tex_coord")?.uv = None;
        Ok(())
    }

    /// Sets the current texture coordinate.
    pub fn tex_coord(&mut self, uv: Vec2) -> Result<(), CoreError> {
        if !uv.is_finite() {
            return Err(CoreError::NonFinite {
                call: "tex_coord",
                what: format!("texture coordinate {uv}"),
            });
        }
        self.def_mut("tex_coord")?.uv = Some(uv);
        Ok(())
    }

    // ----- materials -----------------------------------------------------

    /// Adds a texture to the table.
    pub fn create_texture(&mut self, t: Texture) -> TextureId {
        self.textures.push(Arc::new(t));
        self.textures_dirty = true;
        TextureId((self.textures.len() - 1) as u32)
    }

    /// Adds a material to the table.
    pub fn create_material(&mut self, m: Material) -> Result<MaterialId, CoreError> {
        if !m.is_finite() {
            return Err(CoreError::NonFinite {
                call: "create_material",
                what: format!("material {m:?}"),
            });
        }
        if let Some(t) = [m.texture, m.emission_texture]
            .into_iter()
            .flatten()
            .find(|t| t.0 as usize >= self.textures.len())
        {
            return Err(CoreError::UnknownTexture {
                call: "create_material",
                id: t,
            });
        }
        self.materials.push(m);
        self.materials_dirty = true;
        Ok(MaterialId((self.materials.len() - 1) as u32))
    }

    /// Binds the material for the following triangles.
    pub fn material(&mut self, id: MaterialId) -> Result<(), CoreError> {
        if id.0 as usize >= self.materials.len() {
            return Err(CoreError::UnknownMaterial { call: "material", id });
        }
        self.current_material = id;
        Ok(())
    }

    /// The current material.
    #[must_use]
    pub fn current_material(&self) -> MaterialId {
        self.current_material
    }

    // ----- matrix stack --------------------------------------------------

    /// The current matrix.
    #[must_use]
    pub fn current_matrix(&self) -> Mat4 {
        self.matrices.top()
    }

    /// Depth of the matrix stack (1 when nothing is pushed).
    #[must_use]
    pub fn matrix_depth(&self) -> usize {
        self.matrices.depth()
    }

    fn finite_affine(call: &'static str, m: &Mat4) -> Result<(), CoreError> {
        if !m.is_finite() {
            return Err(CoreError::NonFinite {
                call,
                what: format!("matrix {m}"),
            });
        }
        let row = m.row(3);
        if row != glam::Vec4::W {
            return Err(CoreError::NotAffine {
                call,
                row: row.to_array(),
            });
        }
        Ok(())
    }

    /// Replaces the current matrix by the identity.
    pub fn load_identity(&mut self) {
        *self.matrices.top_mut() = Mat4::IDENTITY;
    }

    /// Replaces the current matrix.
    pub fn load_matrix(&mut self, m: Mat4) -> Result<(), CoreError> {
        Self::finite_affine("load_matrix", &m)?;
        *self.matrices.top_mut() = m;
        Ok(())
    }

    /// Multiplies the current matrix by `m` on the right (OpenGL order).
    pub fn mult_matrix(&mut self, m: Mat4) -> Result<(), CoreError> {
        Self::finite_affine("mult_matrix", &m)?;
        let r = self.matrices.top() * m;
        Self::finite_affine("mult_matrix", &r)?;
        *self.matrices.top_mut() = r;
        Ok(())
    }

    /// Multiplies by a translation.
    pub fn translate(&mut self, t: Vec3) -> Result<(), CoreError> {
        if !t.is_finite() {
            return Err(CoreError::NonFinite {
                call: "translate",
                what: format!("offset {t}"),
            });
        }
        self.mult_matrix(Mat4::from_translation(t))
    }

    /// Multiplies by a rotation of `degrees` about `axis` (any non-zero length).
    pub fn rotate(&mut self, degrees: f32, axis: Vec3) -> Result<(), CoreError> {
        if !degrees.is_finite() || !axis.is_finite() {
            return Err(CoreError::NonFinite {
                call: "rotate",
                what: format!("angle {degrees} about {axis}"),
            });
        }
        let Some(a) = axis.try_normalize() else {
            return Err(CoreError::NonFinite {
                call: "rotate",
                what: format!("axis {axis} (zero length has no direction)"),
            });
        };
        self.mult_matrix(Mat4::from_axis_angle(a, degrees.to_radians()))
    }

    /// Multiplies by a scale.
    pub fn scale(&mut self, s: Vec3) -> Result<(), CoreError> {
        if !s.is_finite() {
            return Err(CoreError::NonFinite {
                call: "scale",
                what: format!("factors {s}"),
            });
        }
        self.mult_matrix(Mat4::from_scale(s))
    }

    /// Pushes a copy of the current matrix.
    pub fn push_matrix(&mut self) -> Result<(), CoreError> {
        self.matrices.push()
    }

    /// Pops the current matrix.
    pub fn pop_matrix(&mut self) -> Result<(), CoreError> {
        self.matrices.pop()
    }

    // ----- instances -----------------------------------------------------

    /// Places a defined object in the world with the current matrix.
    pub fn instantiate(&mut self, object: ObjectId) -> Result<InstanceId, CoreError> {
        self.no_definition("instantiate")?;
        let slot = self.object_slot("instantiate", object)?;
        if slot.geometry.is_none() && slot.pending.is_none() {
            return Err(CoreError::UndefinedObject {
                call: "instantiate",
                id: object,
            });
        }
        let transform = check_transform("instantiate", &self.matrices.top())?;
        let id = self.place(object, transform);
        if let Some(log) = &mut self.change_log {
            log.instances.insert(id.index);
        }
        Ok(id)
    }

    fn place(&mut self, object: ObjectId, transform: Affine3A) -> InstanceId {
        let fresh = InstanceSlot {
            generation: 0,
            alive: true,
            object,
            transform,
        };
        if let Some(i) = self.free_instances.pop() {
            let s = &mut self.instances[i as usize];
            let generation = s.generation;
            *s = InstanceSlot { generation, ..fresh };
            InstanceId { index: i, generation }
        } else {
            self.instances.push(fresh);
            InstanceId {
                index: (self.instances.len() - 1) as u32,
                generation: 0,
            }
        }
    }

    fn instance_slot_mut(&mut self, call: &'static str, id: InstanceId) -> Result<&mut InstanceSlot, CoreError> {
        match self.instances.get_mut(id.index as usize) {
            Some(s) if s.alive && s.generation == id.generation => Ok(s),
            _ => Err(CoreError::UnknownInstance { call, id }),
        }
    }

    /// Sets an instance's object-to-world transform (affine motion).
    pub fn set_instance_transform(&mut self, id: InstanceId, m: Mat4) -> Result<(), CoreError> {
        let t = check_transform("set_instance_transform", &m)?;
        self.instance_slot_mut("set_instance_transform", id)?.transform = t;
        if let Some(log) = &mut self.change_log {
            log.instances.insert(id.index);
        }
        Ok(())
    }

    /// The object and transform of an instance.
    pub fn instance(&self, id: InstanceId) -> Result<(ObjectId, Mat4), CoreError> {
        match self.instances.get(id.index as usize) {
            Some(s) if s.alive && s.generation == id.generation => Ok((s.object, Mat4::from(s.transform))),
            _ => Err(CoreError::UnknownInstance { call: "instance", id }),
        }
    }

    /// Removes an instance; its id becomes stale.
    pub fn remove_instance(&mut self, id: InstanceId) -> Result<(), CoreError> {
        if let Some(log) = &mut self.change_log {
            log.instances.insert(id.index);
        }
        let s = self.instance_slot_mut("remove_instance", id)?;
        s.alive = false;
        // As for objects: a slot whose generation would wrap is retired.
        if let Some(g) = s.generation.checked_add(1) {
            s.generation = g;
            self.free_instances.push(id.index);
        }
        Ok(())
    }

    /// Why the background SAH build of an object's current geometry failed
    /// (`None`: it did not fail, or was not tried). A failed build is
    /// reported once in [`CommitStats::promotions_failed`](crate::CommitStats)
    /// and not retried until the object is redefined.
    pub fn promotion_failure(&self, id: ObjectId) -> Result<Option<&str>, CoreError> {
        let slot = self.object_slot("promotion_failure", id)?;
        Ok(match &slot.promotion {
            Some(Promotion::Failed { version, reason }) if *version == slot.version => Some(reason),
            _ => None,
        })
    }

    pub(crate) fn ensure_not_defining(&self, call: &'static str) -> Result<(), CoreError> {
        self.no_definition(call)
    }
}

/// Failures the unit tests inject into a commit; compiled into test builds
/// only, so the production [`Context`] carries no hooks.
#[cfg(test)]
#[derive(Default)]
pub(crate) struct TestHooks {
    /// Object builds left before an injected build failure.
    pub(crate) fail_builds: Option<usize>,
    /// Background builds fail.
    pub(crate) fail_promotions: bool,
}

#[cfg(test)]
mod draw_elements_tests {
    use super::*;

    /// The pending definition of `id`.
    fn pending(ctx: &Context, id: ObjectId) -> ObjectMesh {
        ctx.objects[id.index as usize].pending.clone().expect("defined")
    }

    /// Positions of a bent strip with a degenerate corner, normals (one
    /// zero), texture coordinates.
    fn arrays() -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec2>) {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.2),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, -0.3),
            Vec3::new(0.0, 2.0, 0.5),
            Vec3::new(0.0, 2.0, 0.5),
        ];
        let n = vec![Vec3::Z, Vec3::new(0.1, 0.0, 1.0), Vec3::Z, Vec3::ZERO, Vec3::Y, Vec3::Y];
        let t = (0..6)
            .map(|i| Vec2::new(i as f32 * 0.25, 1.0 - i as f32 * 0.1))
            .collect();
        (p, n, t)
    }

    #[test]
    fn draw_elements_gives_the_triangles_of_the_same_calls_vertex_by_vertex() {
        let (p, n, t) = arrays();
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 1.0),
            glam::Quat::from_rotation_y(0.7),
            Vec3::new(1.0, -2.0, 3.0),
        );
        for kind in [
            PrimitiveKind::Triangles,
            PrimitiveKind::TriangleStrip,
            PrimitiveKind::TriangleFan,
        ] {
            let indices: Vec<u32> = vec![0, 1, 2, 2, 1, 3, 4, 5, 3];
            for with in [(true, true), (false, true), (true, false), (false, false)] {
                let normals = with.0.then_some(&n[..]);
                let uvs = with.1.then_some(&t[..]);
                let mut ctx = Context::new();
                let (a, b) = (ctx.gen_object(), ctx.gen_object());
                // The oracle: the same primitive vertex by vertex.
                ctx.begin_object(a).unwrap();
                ctx.mult_matrix(m).unwrap();
                ctx.begin(kind).unwrap();
                for &i in &indices {
                    let i = i as usize;
                    match normals {
                        Some(ns) if ns[i] != Vec3::ZERO => ctx.normal(ns[i]).unwrap(),
                        _ => ctx.clear_normal().unwrap(),
                    }
                    if let Some(ts) = uvs {
                        ctx.tex_coord(ts[i]).unwrap();
                    }
                    ctx.vertex(p[i]).unwrap();
                }
                ctx.end().unwrap();
                ctx.end_object().unwrap();
                ctx.begin_object(b).unwrap();
                ctx.mult_matrix(m).unwrap();
                let arr = VertexArrays {
                    positions: &p,
                    normals,
                    uvs,
                };
                ctx.draw_elements(kind, &arr, &indices).unwrap();
                ctx.end_object().unwrap();
                let (want, got) = (pending(&ctx, a), pending(&ctx, b));
                assert!(got.dropped > 0, "{kind:?}: the degenerate triangle is dropped");
                assert_eq!(got, want, "{kind:?} {with:?}: the same bytes");
            }
        }
    }

    #[test]
    fn broken_arrays_are_typed_errors_and_add_nothing() {
        let (p, n, t) = arrays();
        let mut ctx = Context::new();
        let id = ctx.gen_object();
        let arr = VertexArrays {
            positions: &p,
            normals: Some(&n),
            uvs: Some(&t),
        };
        assert!(matches!(
            ctx.draw_elements(PrimitiveKind::Triangles, &arr, &[0, 1, 2]),
            Err(CoreError::NotInObject { .. })
        ));
        ctx.begin_object(id).unwrap();
        let e = ctx
            .draw_elements(PrimitiveKind::Triangles, &arr, &[0, 1, 6])
            .unwrap_err();
        assert!(
            matches!(
                e,
                CoreError::VertexIndex {
                    index: 6,
                    at: 2,
                    vertices: 6,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("draw_elements: index 6"), "{e}");
        let short = VertexArrays {
            normals: Some(&n[..3]),
            ..arr
        };
        let e = ctx
            .draw_elements(PrimitiveKind::Triangles, &short, &[0, 1, 2])
            .unwrap_err();
        assert!(e.to_string().contains("normal array has 3 entries"), "{e}");
        let mut bad = p.clone();
        bad[4].y = f32::NAN;
        let nan = VertexArrays { positions: &bad, ..arr };
        let e = ctx
            .draw_elements(PrimitiveKind::Triangles, &nan, &[0, 1, 2])
            .unwrap_err();
        assert!(e.to_string().contains("position 4"), "{e}");
        let mut far = p.clone();
        far[1].x = 1e30;
        let e = ctx
            .draw_elements(
                PrimitiveKind::Triangles,
                &VertexArrays { positions: &far, ..arr },
                &[0, 1, 2],
            )
            .unwrap_err();
        assert!(matches!(e, CoreError::CoordinateLimit { .. }), "{e}");
        let e = ctx.draw_elements(PrimitiveKind::Triangles, &arr, &[0, 1]).unwrap_err();
        assert!(matches!(e, CoreError::IncompletePrimitive { .. }), "{e}");
        ctx.begin(PrimitiveKind::Triangles).unwrap();
        assert!(matches!(
            ctx.draw_elements(PrimitiveKind::Triangles, &arr, &[0, 1, 2]),
            Err(CoreError::PrimitiveOpen { .. })
        ));
        ctx.end().unwrap();
        ctx.end_object().unwrap();
        assert!(
            pending(&ctx, id).triangles.is_empty(),
            "nothing of a refused call was added"
        );
    }
}
