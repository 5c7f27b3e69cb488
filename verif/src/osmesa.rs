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
//! OSMesa keeps a current context per thread and Mesa has global state; renders are
//! serialised by a lock.

use crate::image::Image;
use crate::reference;
use imagine_pipelines::scene::Scene;
use std::ffi::{CStr, c_char, c_void};
use std::sync::Mutex;

type GLenum = u32;
type GLint = i32;
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
    fn glVertex3f(x: GLfloat, y: GLfloat, z: GLfloat);
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
