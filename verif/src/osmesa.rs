//! OpenGL reference images from Mesa's off-screen renderer, OSMesa (feature `osmesa`).
//!
//! Needs Debian's `libosmesa6-dev` (`apt-get install -y libosmesa6-dev`): `libOSMesa.so`
//! exports the OSMesa entry points and the OpenGL 1.x functions used here, so this module
//! links that one library (hand-written declarations from `GL/osmesa.h` and `GL/gl.h`).
//! Debian 12's OSMesa (Mesa 22.3) is Gallium's: it renders with llvmpipe by default and
//! needs no display, GPU or environment variable; `GALLIUM_DRIVER=softpipe` selects Mesa's
//! slower reference rasterizer instead ([`renderer`] names the one in use, [`tie_rule`]
//! says which samples on edges it owns). (`LIBGL_ALWAYS_SOFTWARE` changes nothing here:
//! OSMesa is always software.)
//!
//! [`render`] draws a scene as fixed-function OpenGL would: an RGBA8 buffer with a 24-bit
//! depth buffer, viewport = window, the scene's matrix loaded as `GL_PROJECTION`
//! (transposed: GL is column-major) with an identity model-view, `GL_DEPTH_TEST` with
//! `GL_LESS`, smooth shading, dithering off, back faces culled when the scene says so
//! (counter-clockwise front faces), colour cleared to opaque black and depth to 1.0, then
//! `glBegin(GL_TRIANGLES)` with `glColor3f` and `glVertex3f` per vertex. Lit scenes get
//! their vertex colours from the reference renderer's lighting ([`reference::vertex_colours`]),
//! so the comparison is about rasterization, interpolation and depth, not about GL's own
//! lighting model. The buffer's row 0 is the bottom row, like [`Image`].
//!
//! [`render_model`] draws a scene file's scene ([`model::Scene`]) with GL's *own*
//! fixed-function lighting, texturing (multitexture) and blending, as the format's contract
//! describes them (see its documentation).
//!
//! OSMesa keeps a current context per thread and Mesa has global state; renders are
//! serialised by a lock.

use crate::image::Image;
use crate::reference;
use imagine_pipelines::scene::mipmap;
use imagine_pipelines::scene::model::{
    self, Blend, Cull, DepthTest, Filter, Shader, Space, TextureMode, Wrap,
};
use imagine_pipelines::scene::{IDENTITY, Scene, window_to_clip};
use std::ffi::{CStr, c_char, c_void};
use std::sync::Mutex;

type GLenum = u32;
type GLint = i32;
type GLuint = u32;
type GLsizei = i32;
type GLfloat = f32;
type GLclampd = f64;
type GLboolean = u8;
type GLbitfield = u32;
type OSMesaContext = *mut c_void;

const GL_RGBA: GLenum = 0x1908;
const GL_UNSIGNED_BYTE: GLenum = 0x1401;
const GL_TRIANGLES: GLenum = 0x0004;
const GL_MODELVIEW: GLenum = 0x1700;
const GL_PROJECTION: GLenum = 0x1701;
const GL_DEPTH_TEST: GLenum = 0x0B71;
const GL_CULL_FACE: GLenum = 0x0B44;
const GL_DITHER: GLenum = 0x0BD0;
const GL_LESS: GLenum = 0x0201;
const GL_SMOOTH: GLenum = 0x1D01;
const GL_BACK: GLenum = 0x0405;
const GL_CCW: GLenum = 0x0901;
const GL_COLOR_BUFFER_BIT: GLbitfield = 0x4000;
const GL_DEPTH_BUFFER_BIT: GLbitfield = 0x0100;
const GL_RENDERER: GLenum = 0x1F01;
const GL_VERSION: GLenum = 0x1F02;
const GL_NO_ERROR: GLenum = 0;
const GL_LEQUAL: GLenum = 0x0203;
const GL_ALWAYS: GLenum = 0x0207;
const GL_FRONT: GLenum = 0x0404;
const GL_FRONT_AND_BACK: GLenum = 0x0408;
const GL_LIGHTING: GLenum = 0x0B50;
const GL_LIGHT_MODEL_LOCAL_VIEWER: GLenum = 0x0B51;
const GL_LIGHT_MODEL_TWO_SIDE: GLenum = 0x0B52;
const GL_LIGHT_MODEL_AMBIENT: GLenum = 0x0B53;
const GL_COLOR_MATERIAL: GLenum = 0x0B57;
const GL_NORMALIZE: GLenum = 0x0BA1;
const GL_AMBIENT: GLenum = 0x1200;
const GL_DIFFUSE: GLenum = 0x1201;
const GL_SPECULAR: GLenum = 0x1202;
const GL_POSITION: GLenum = 0x1203;
const GL_EMISSION: GLenum = 0x1600;
const GL_SHININESS: GLenum = 0x1601;
const GL_LIGHT0: GLenum = 0x4000;
const GL_TEXTURE_2D: GLenum = 0x0DE1;
const GL_TEXTURE0: GLenum = 0x84C0;
const GL_TEXTURE_ENV: GLenum = 0x2300;
const GL_TEXTURE_ENV_MODE: GLenum = 0x2200;
const GL_MODULATE: GLint = 0x2100;
const GL_REPLACE: GLint = 0x1E01;
const GL_TEXTURE_MAG_FILTER: GLenum = 0x2800;
const GL_TEXTURE_MIN_FILTER: GLenum = 0x2801;
const GL_TEXTURE_WRAP_S: GLenum = 0x2802;
const GL_TEXTURE_WRAP_T: GLenum = 0x2803;
const GL_NEAREST: GLint = 0x2600;
const GL_LINEAR: GLint = 0x2601;
const GL_LINEAR_MIPMAP_LINEAR: GLint = 0x2703;
const GL_REPEAT: GLint = 0x2901;
const GL_CLAMP_TO_EDGE: GLint = 0x812F;
const GL_UNPACK_ALIGNMENT: GLenum = 0x0CF5;
const GL_MAX_TEXTURE_UNITS: GLenum = 0x84E2;
const GL_BLEND: GLenum = 0x0BE2;
const GL_ONE: GLenum = 1;
const GL_SRC_ALPHA: GLenum = 0x0302;
const GL_ONE_MINUS_SRC_ALPHA: GLenum = 0x0303;
const OSMESA_RGBA: GLenum = GL_RGBA;

#[link(name = "OSMesa")]
unsafe extern "C" {
    fn OSMesaCreateContextExt(
        format: GLenum,
        depth_bits: GLint,
        stencil_bits: GLint,
        accum_bits: GLint,
        sharelist: OSMesaContext,
    ) -> OSMesaContext;
    fn OSMesaDestroyContext(ctx: OSMesaContext);
    fn OSMesaMakeCurrent(
        ctx: OSMesaContext,
        buffer: *mut c_void,
        kind: GLenum,
        width: GLsizei,
        height: GLsizei,
    ) -> GLboolean;

    fn glViewport(x: GLint, y: GLint, width: GLsizei, height: GLsizei);
    fn glMatrixMode(mode: GLenum);
    fn glLoadMatrixf(m: *const GLfloat);
    fn glLoadIdentity();
    fn glEnable(cap: GLenum);
    fn glDisable(cap: GLenum);
    fn glDepthFunc(func: GLenum);
    fn glShadeModel(mode: GLenum);
    fn glCullFace(mode: GLenum);
    fn glFrontFace(mode: GLenum);
    fn glClearColor(r: GLfloat, g: GLfloat, b: GLfloat, a: GLfloat);
    fn glClearDepth(depth: GLclampd);
    fn glClear(mask: GLbitfield);
    fn glBegin(mode: GLenum);
    fn glEnd();
    fn glColor3f(r: GLfloat, g: GLfloat, b: GLfloat);
    fn glNormal3f(x: GLfloat, y: GLfloat, z: GLfloat);
    fn glMultMatrixf(m: *const GLfloat);
    fn glPushMatrix();
    fn glPopMatrix();
    fn glLightfv(light: GLenum, pname: GLenum, params: *const GLfloat);
    fn glLightModelfv(pname: GLenum, params: *const GLfloat);
    fn glLightModeli(pname: GLenum, param: GLint);
    fn glMaterialfv(face: GLenum, pname: GLenum, params: *const GLfloat);
    fn glMaterialf(face: GLenum, pname: GLenum, param: GLfloat);
    fn glVertex3f(x: GLfloat, y: GLfloat, z: GLfloat);
    fn glGenTextures(n: GLsizei, textures: *mut GLuint);
    fn glBindTexture(target: GLenum, texture: GLuint);
    fn glTexImage2D(
        target: GLenum,
        level: GLint,
        internal_format: GLint,
        width: GLsizei,
        height: GLsizei,
        border: GLint,
        format: GLenum,
        kind: GLenum,
        pixels: *const c_void,
    );
    fn glTexParameteri(target: GLenum, pname: GLenum, param: GLint);
    fn glTexEnvi(target: GLenum, pname: GLenum, param: GLint);
    fn glPixelStorei(pname: GLenum, param: GLint);
    fn glActiveTexture(texture: GLenum);
    fn glMultiTexCoord2f(target: GLenum, s: GLfloat, t: GLfloat);
    fn glGetIntegerv(pname: GLenum, params: *mut GLint);
    fn glBlendFunc(sfactor: GLenum, dfactor: GLenum);
    fn glColorMask(r: GLboolean, g: GLboolean, b: GLboolean, a: GLboolean);
    fn glFinish();
    fn glGetError() -> GLenum;
    fn glGetString(name: GLenum) -> *const c_char;
}

static LOCK: Mutex<()> = Mutex::new(());

/// An OSMesa context made current on a buffer; destroyed on drop.
struct Context {
    ctx: OSMesaContext,
    buffer: Vec<[u8; 4]>,
}

impl Context {
    /// Must be called with `LOCK` held.
    fn new(width: u32, height: u32) -> Result<Context, String> {
        // SAFETY: plain FFI call; a null share list is allowed.
        let ctx = unsafe { OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, std::ptr::null_mut()) };
        if ctx.is_null() {
            return Err("OSMesaCreateContextExt failed (is libosmesa6 installed?)".into());
        }
        let mut context = Context {
            ctx,
            buffer: vec![[0; 4]; width as usize * height as usize],
        };
        // SAFETY: the buffer holds width × height RGBA8 pixels, 4-byte aligned, and lives
        // as long as the context (both are dropped together, the context first).
        let ok = unsafe {
            OSMesaMakeCurrent(
                context.ctx,
                context.buffer.as_mut_ptr().cast(),
                GL_UNSIGNED_BYTE,
                width as GLsizei,
                height as GLsizei,
            )
        };
        if ok == 0 {
            return Err(format!(
                "OSMesaMakeCurrent failed for a {width}x{height} buffer"
            ));
        }
        Ok(context)
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: the context was created by OSMesaCreateContextExt and is destroyed once.
        unsafe { OSMesaDestroyContext(self.ctx) };
    }
}

fn gl_string(name: GLenum) -> String {
    // SAFETY: a context is current; glGetString returns a static NUL-terminated string or
    // null.
    let s = unsafe { glGetString(name) };
    if s.is_null() {
        return String::new();
    }
    // SAFETY: non-null and NUL-terminated per the GL specification.
    unsafe { CStr::from_ptr(s) }.to_string_lossy().into_owned()
}

/// The GL renderer and version strings OSMesa reports (e.g. `llvmpipe (LLVM 15.0.6, 256
/// bits)`, `4.5 (Compatibility Profile) Mesa 22.3.6`).
pub fn renderer() -> Result<String, String> {
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let _context = Context::new(1, 1)?;
    Ok(format!(
        "{}; {}",
        gl_string(GL_RENDERER),
        gl_string(GL_VERSION)
    ))
}

/// The tie rule of the OSMesa driver in use ([`reference::TieRule`]): `BottomLeft` for
/// llvmpipe, `TopRight` for softpipe; an error for other drivers.
pub fn tie_rule() -> Result<reference::TieRule, String> {
    let name = renderer()?;
    if name.starts_with("llvmpipe") {
        Ok(reference::TieRule::BottomLeft)
    } else if name.starts_with("softpipe") {
        Ok(reference::TieRule::TopRight)
    } else {
        Err(format!(
            "no known tie rule for the OSMesa renderer `{name}`"
        ))
    }
}

/// Renders a scene with OSMesa (see the module comment).
pub fn render(scene: &Scene) -> Result<Image, String> {
    scene.validate().map_err(|e| e.to_string())?;
    let colours = reference::vertex_colours(scene);
    let (width, height) = (scene.width, scene.height);
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let context = Context::new(width, height)?;
    // GL is column-major: element (row i, column j) at j·4 + i.
    let mvp = scene.mvp();
    let column_major: [f32; 16] = std::array::from_fn(|k| mvp[(k % 4) * 4 + k / 4]);
    // SAFETY: a context is current on this thread (we hold the lock); all arguments are
    // plain values or a pointer to 16 floats.
    let error = unsafe {
        glViewport(0, 0, width as GLsizei, height as GLsizei);
        glMatrixMode(GL_PROJECTION);
        glLoadMatrixf(column_major.as_ptr());
        glMatrixMode(GL_MODELVIEW);
        glLoadIdentity();
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LESS);
        glShadeModel(GL_SMOOTH);
        glDisable(GL_DITHER);
        glFrontFace(GL_CCW);
        if scene.cull_back {
            glCullFace(GL_BACK);
            glEnable(GL_CULL_FACE);
        } else {
            glDisable(GL_CULL_FACE);
        }
        glClearColor(0.0, 0.0, 0.0, 1.0);
        glClearDepth(1.0);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glBegin(GL_TRIANGLES);
        for (p, c) in scene.positions.iter().zip(&colours) {
            glColor3f(c[0] as f32, c[1] as f32, c[2] as f32);
            glVertex3f(p[0], p[1], p[2]);
        }
        glEnd();
        glFinish();
        glGetError()
    };
    if error != GL_NO_ERROR {
        return Err(format!(
            "OpenGL error 0x{error:04X} while rendering `{}`",
            scene.name
        ));
    }
    Ok(Image {
        width,
        height,
        pixels: context.buffer.clone(),
    })
}

/// A row-major matrix in GL's column-major order: element (row i, column j) at j·4 + i.
fn column_major(m: &[f32; 16]) -> [f32; 16] {
    std::array::from_fn(|k| m[(k % 4) * 4 + k / 4])
}

fn rgba(c: [f32; 3]) -> [f32; 4] {
    [c[0], c[1], c[2], 1.0]
}

/// Creates and fills one texture object per scene texture (see [`render_model`]); returns
/// their names. Must be called with a context current.
fn upload_textures(scene: &model::Scene) -> Vec<GLuint> {
    scene
        .textures
        .iter()
        .map(|texture| {
            let levels = match texture.filter {
                Filter::Trilinear => mipmap::pyramid(texture),
                Filter::Nearest | Filter::Linear => vec![mipmap::Level {
                    width: texture.width,
                    height: texture.height,
                    texels: texture.texels.clone(),
                }],
            };
            let (min, mag) = match texture.filter {
                Filter::Nearest => (GL_NEAREST, GL_NEAREST),
                Filter::Linear => (GL_LINEAR, GL_LINEAR),
                Filter::Trilinear => (GL_LINEAR_MIPMAP_LINEAR, GL_LINEAR),
            };
            let wrap = match texture.wrap {
                Wrap::Repeat => GL_REPEAT,
                Wrap::Clamp => GL_CLAMP_TO_EDGE,
            };
            let mut name: GLuint = 0;
            // SAFETY: a context is current (the caller holds the lock); each level's bytes
            // are width × height RGBA8 pixels, read during the call.
            unsafe {
                glActiveTexture(GL_TEXTURE0);
                glGenTextures(1, &mut name);
                glBindTexture(GL_TEXTURE_2D, name);
                glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
                for (k, level) in levels.iter().enumerate() {
                    let bytes: Vec<u8> =
                        level.texels.iter().flat_map(|w| w.to_le_bytes()).collect();
                    glTexImage2D(
                        GL_TEXTURE_2D,
                        k as GLint,
                        GL_RGBA as GLint,
                        level.width as GLsizei,
                        level.height as GLsizei,
                        0,
                        GL_RGBA,
                        GL_UNSIGNED_BYTE,
                        bytes.as_ptr().cast(),
                    );
                }
                glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, min);
                glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, mag);
                glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, wrap);
                glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, wrap);
            }
            name
        })
        .collect()
}

/// Renders a scene file's scene with OSMesa and GL's own fixed-function pipeline:
///
/// * `glViewport` = window; `GL_PROJECTION` = the camera's projection and `GL_MODELVIEW`
///   = its view (transposed: GL is column-major); with that view loaded, each light gets
///   `glLightfv(GL_POSITION, (x, y, z, 1))` — GL transforms it to eye space — and its
///   ambient, diffuse and specular colours; `GL_LIGHT_MODEL_AMBIENT` = the scene's
///   ambient, `GL_LIGHT_MODEL_LOCAL_VIEWER` = 1, two-sided lighting off, `GL_NORMALIZE`
///   on, `GL_COLOR_MATERIAL` off, no emission;
/// * per object in order: for a world-space object `glPushMatrix`, `glMultMatrixf(model)`,
///   draw, `glPopMatrix`; a window-space object gets `window_to_clip` as its projection and
///   its model matrix alone as model-view (the camera's matrices are restored after);
/// * a `lit` material enables `GL_LIGHTING` and sets `glMaterialfv` ambient, diffuse and
///   specular and `glMaterialf` shininess on `GL_FRONT_AND_BACK`, then each corner gets
///   `glNormal3f` (the mesh's normal, or the triangle's geometric normal when the mesh
///   has none) and `glVertex3f`; an `unlit` one disables lighting and gives each corner
///   `glColor3f` (the mesh's colour or the object's);
/// * depth test per the scene (`GL_LESS`, `GL_LEQUAL`, `GL_ALWAYS`), cull face per the
///   scene (counter-clockwise front faces), smooth shading, dithering off, colour cleared
///   to the background and depth to 1.0;
/// * one texture object per scene texture, RGBA8 (`glTexImage2D`, `GL_RGBA`,
///   `GL_UNSIGNED_BYTE`, unpack alignment 1, row 0 at the bottom as GL has it): level 0,
///   and for `trilinear` every level of [`mipmap::pyramid`] (so Mesa samples the same
///   levels as the reference); `GL_TEXTURE_MIN_FILTER` `GL_NEAREST`, `GL_LINEAR` or
///   `GL_LINEAR_MIPMAP_LINEAR`, `GL_TEXTURE_MAG_FILTER` `GL_NEAREST` for `nearest` and
///   `GL_LINEAR` otherwise, `GL_TEXTURE_WRAP_S`/`_T` `GL_REPEAT` or `GL_CLAMP_TO_EDGE`;
/// * a textured material binds its textures to units 0, 1, … in order (multitexture,
///   GL 1.3: `glActiveTexture`), each enabled with `glTexEnvi(GL_TEXTURE_ENV_MODE)`
///   `GL_MODULATE` or `GL_REPLACE`, the units beyond disabled, and each corner gets
///   `glMultiTexCoord2f` for every unit (the mesh's one set of texcoords);
/// * `blend`: `glEnable(GL_BLEND)` with `glBlendFunc(GL_SRC_ALPHA,
///   GL_ONE_MINUS_SRC_ALPHA)` (`alpha`) or `(GL_ONE, GL_ONE)` (`add`); alpha is masked
///   off (`glColorMask`), the buffer's alpha stays 1 — the contract's framebuffer is RGB.
///
/// Scenes the reference refuses ([`crate::reference_model::check`]) are refused.
pub fn render_model(scene: &model::Scene) -> Result<Image, String> {
    crate::reference_model::check(scene).map_err(|e| e.to_string())?;
    let (width, height) = (scene.width, scene.height);
    let _guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let context = Context::new(width, height)?;
    let projection = column_major(&scene.camera.projection);
    let view = column_major(&scene.camera.view);
    let window_projection = column_major(&window_to_clip(width, height));
    let identity = column_major(&IDENTITY);
    let [br, bg, bb] = scene.background;
    // SAFETY: a context is current on this thread (we hold the lock); all arguments are
    // plain values or pointers to 4 or 16 floats that outlive the calls.
    let error = unsafe {
        glViewport(0, 0, width as GLsizei, height as GLsizei);
        glMatrixMode(GL_PROJECTION);
        glLoadMatrixf(projection.as_ptr());
        glMatrixMode(GL_MODELVIEW);
        glLoadMatrixf(view.as_ptr());
        for (i, light) in scene.lights.iter().enumerate() {
            let id = GL_LIGHT0 + i as GLenum;
            let [x, y, z] = light.position;
            glLightfv(id, GL_POSITION, [x, y, z, 1.0].as_ptr());
            glLightfv(id, GL_AMBIENT, rgba(light.ambient).as_ptr());
            glLightfv(id, GL_DIFFUSE, rgba(light.diffuse).as_ptr());
            glLightfv(id, GL_SPECULAR, rgba(light.specular).as_ptr());
            glEnable(id);
        }
        glLightModelfv(GL_LIGHT_MODEL_AMBIENT, rgba(scene.ambient).as_ptr());
        glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, 1);
        glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, 0);
        glMaterialfv(
            GL_FRONT_AND_BACK,
            GL_EMISSION,
            [0.0, 0.0, 0.0, 1.0].as_ptr(),
        );
        glDisable(GL_COLOR_MATERIAL);
        glEnable(GL_NORMALIZE);
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(match scene.pipeline.depth_test {
            DepthTest::Less => GL_LESS,
            DepthTest::Lequal => GL_LEQUAL,
            DepthTest::Always => GL_ALWAYS,
        });
        glShadeModel(GL_SMOOTH);
        glDisable(GL_DITHER);
        glFrontFace(GL_CCW);
        match scene.pipeline.cull {
            Cull::Back => {
                glCullFace(GL_BACK);
                glEnable(GL_CULL_FACE);
            }
            Cull::Front => {
                glCullFace(GL_FRONT);
                glEnable(GL_CULL_FACE);
            }
            Cull::None => glDisable(GL_CULL_FACE),
        }
        glClearColor(br, bg, bb, 1.0);
        glClearDepth(1.0);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glColorMask(1, 1, 1, 0);
        match scene.pipeline.blend {
            Blend::None => glDisable(GL_BLEND),
            Blend::Alpha => {
                glEnable(GL_BLEND);
                glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            }
            Blend::Add => {
                glEnable(GL_BLEND);
                glBlendFunc(GL_ONE, GL_ONE);
            }
        }
        let names = upload_textures(scene);
        let most_units = scene
            .materials
            .iter()
            .map(|m| m.textures.len())
            .max()
            .unwrap_or(0);
        let mut max_units: GLint = 0;
        glGetIntegerv(GL_MAX_TEXTURE_UNITS, &mut max_units);
        if most_units > max_units.max(0) as usize {
            return Err(format!(
                "`{}` has a material with {most_units} textures: OSMesa has {max_units} units",
                scene.name
            ));
        }

        for object in &scene.objects {
            let window = object.space == Space::Window;
            if window {
                glMatrixMode(GL_PROJECTION);
                glLoadMatrixf(window_projection.as_ptr());
                glMatrixMode(GL_MODELVIEW);
                glLoadMatrixf(identity.as_ptr());
            } else {
                glPushMatrix();
            }
            glMultMatrixf(column_major(&object.model).as_ptr());
            let material = &scene.materials[object.material];
            let lit = material.shader == Shader::Lit;
            if lit {
                glEnable(GL_LIGHTING);
                glMaterialfv(
                    GL_FRONT_AND_BACK,
                    GL_AMBIENT,
                    rgba(material.ambient).as_ptr(),
                );
                glMaterialfv(
                    GL_FRONT_AND_BACK,
                    GL_DIFFUSE,
                    rgba(material.diffuse).as_ptr(),
                );
                glMaterialfv(
                    GL_FRONT_AND_BACK,
                    GL_SPECULAR,
                    rgba(material.specular).as_ptr(),
                );
                glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, material.shininess);
            } else {
                glDisable(GL_LIGHTING);
            }
            let units = material.textures.len();
            for unit in 0..most_units {
                glActiveTexture(GL_TEXTURE0 + unit as GLenum);
                match material.textures.get(unit) {
                    Some(&t) => {
                        glEnable(GL_TEXTURE_2D);
                        glBindTexture(GL_TEXTURE_2D, names[t]);
                        glTexEnvi(
                            GL_TEXTURE_ENV,
                            GL_TEXTURE_ENV_MODE,
                            match material.texture_mode {
                                TextureMode::Modulate => GL_MODULATE,
                                TextureMode::Replace => GL_REPLACE,
                            },
                        );
                    }
                    None => glDisable(GL_TEXTURE_2D),
                }
            }
            let mesh = &object.mesh;
            glBegin(GL_TRIANGLES);
            for &t in &mesh.triangles {
                let normals = crate::reference_model::corner_normals(mesh, t);
                for (&i, n) in t.iter().zip(normals) {
                    let i = i as usize;
                    if lit {
                        glNormal3f(n[0] as f32, n[1] as f32, n[2] as f32);
                    } else {
                        let [r, g, b] = *mesh.colours.get(i).unwrap_or(&object.colour);
                        glColor3f(r, g, b);
                    }
                    if units > 0 {
                        let [s, t] = mesh.texcoords[i];
                        for unit in 0..units {
                            glMultiTexCoord2f(GL_TEXTURE0 + unit as GLenum, s, t);
                        }
                    }
                    let [x, y, z] = mesh.positions[i];
                    glVertex3f(x, y, z);
                }
            }
            glEnd();
            if window {
                glMatrixMode(GL_PROJECTION);
                glLoadMatrixf(projection.as_ptr());
                glMatrixMode(GL_MODELVIEW);
                glLoadMatrixf(view.as_ptr());
            } else {
                glPopMatrix();
            }
        }
        glFinish();
        glGetError()
    };
    if error != GL_NO_ERROR {
        return Err(format!(
            "OpenGL error 0x{error:04X} while rendering `{}`",
            scene.name
        ));
    }
    Ok(Image {
        width,
        height,
        pixels: context.buffer.clone(),
    })
}
