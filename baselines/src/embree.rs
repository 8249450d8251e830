//! Intel Embree 3 (Debian's `libembree-dev`, 3.13) through a small FFI of our own: a device,
//! a triangle scene built from our mesh, and closest-hit / any-hit queries for single rays and
//! packets of 4, 8 and 16 rays.
//!
//! Only with the `embree` feature. Every `unsafe` of the workspace's Embree use is in this
//! module, each with its `// SAFETY:` argument; what it exports is safe: [`Device`] and
//! [`EmbreeScene`] release their handles when dropped, rays go in as our [`Ray`] and come
//! out as our [`Hit`].
//!
//! Conventions, so that Embree traces exactly our rays:
//! - triangles are passed in the order of the mesh, none dropped (Embree skips degenerate
//!   ones itself), so Embree's `primID` is our triangle index ([`Hit::prim`]);
//! - `tnear` / `tfar` are our `t_min` / `t_max`, and directions are passed as they are
//!   (unnormalised shadow rays too), so `t` is in the same units;
//! - Embree requires `tnear >= 0` (Debian's libembree3 is built with assertions and aborts
//!   the process on `ray.tnear() >= 0.0f`), so a ray with a negative `t_min` is moved back
//!   along itself ([`EmbreeRay`]): origin `o + t_min * d`, `tnear = 0`, `tfar = t_max - t_min`,
//!   and the hit's `t` is shifted back by `t_min`. This is exact in real arithmetic; in `f32`
//!   the moved origin is rounded (by up to an ulp of `|o| + |t_min * d|` per component),
//!   `tfar` by half an ulp of `t_max - t_min`, and the reported `t` by half an ulp of `t`
//!   plus the origin's error along the ray, so such a hit may differ from an unshifted
//!   trace by a few ulps of `|t_min|`, and hits within that distance of either end of the
//!   interval may fall in or out of it;
//! - a ray Embree cannot take (a NaN interval, `t_min = -inf` or a moved origin that is not
//!   finite, components beyond Embree's `FLT_LARGE` = 1.844e18, which its `ray.valid()`
//!   assertion also aborts on) is not sent to Embree: it is answered as a miss (not
//!   occluded). Rays of rendering never are; a ray file may hold them.
//! - Embree's `u`, `v` weight the second and third vertex, as ours do.
//!
//! The struct layouts below are those of `rtcore_ray.h` / `rtcore_common.h` with
//! `RTC_MAX_INSTANCE_LEVEL_COUNT = 1` and `RTC_MIN_WIDTH = 0` (Debian's build); the tests
//! check sizes and alignments against the values a C compiler gives for that header.

use std::ffi::{CString, c_int, c_void};
use std::ptr::NonNull;

use glam::Vec3;
use kdtree::{Hit, Ray};

/// The raw C API: the types and functions we use, as declared in `embree3/rtcore*.h`.
mod sys {
    use std::ffi::{c_char, c_int, c_uint, c_void};

    /// `RTCDevice`, an opaque handle.
    pub type RtcDevice = *mut c_void;
    /// `RTCScene`, an opaque handle.
    pub type RtcScene = *mut c_void;
    /// `RTCGeometry`, an opaque handle.
    pub type RtcGeometry = *mut c_void;

    /// `RTC_INVALID_GEOMETRY_ID`.
    pub const INVALID_GEOMETRY_ID: c_uint = u32::MAX;
    /// `RTC_GEOMETRY_TYPE_TRIANGLE`.
    pub const GEOMETRY_TYPE_TRIANGLE: c_int = 0;
    /// `RTC_BUFFER_TYPE_INDEX`.
    pub const BUFFER_TYPE_INDEX: c_int = 0;
    /// `RTC_BUFFER_TYPE_VERTEX`.
    pub const BUFFER_TYPE_VERTEX: c_int = 1;
    /// `RTC_FORMAT_UINT3`.
    pub const FORMAT_UINT3: c_int = 0x5003;
    /// `RTC_FORMAT_FLOAT3`.
    pub const FORMAT_FLOAT3: c_int = 0x9003;
    /// `RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT`.
    pub const CONTEXT_FLAG_INCOHERENT: c_int = 0;
    /// `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`.
    pub const CONTEXT_FLAG_COHERENT: c_int = 1;
    /// `RTC_SCENE_FLAG_NONE`.
    pub const SCENE_FLAG_NONE: c_int = 0;

    /// `struct RTCIntersectContext` (no `instStackSize`, no `minWidthDistanceFactor` in this
    /// build).
    #[repr(C)]
    pub struct RtcIntersectContext {
        /// `enum RTCIntersectContextFlags`.
        pub flags: c_int,
        /// `RTCFilterFunctionN`, null here.
        pub filter: Option<unsafe extern "C" fn(*const c_void)>,
        /// The instance id stack, `RTC_INVALID_GEOMETRY_ID` outside instances.
        pub inst_id: [c_uint; 1],
    }

    /// `struct RTCRay`.
    #[repr(C, align(16))]
    #[derive(Clone, Copy, Default)]
    pub struct RtcRay {
        pub org: [f32; 3],
        pub tnear: f32,
        pub dir: [f32; 3],
        pub time: f32,
        pub tfar: f32,
        pub mask: c_uint,
        pub id: c_uint,
        pub flags: c_uint,
    }

    /// `struct RTCHit`.
    #[repr(C, align(16))]
    #[derive(Clone, Copy, Default)]
    pub struct RtcHit {
        pub ng: [f32; 3],
        pub u: f32,
        pub v: f32,
        pub prim_id: c_uint,
        pub geom_id: c_uint,
        pub inst_id: [c_uint; 1],
    }

    /// `struct RTCRayHit`.
    #[repr(C)]
    #[derive(Clone, Copy, Default)]
    pub struct RtcRayHit {
        pub ray: RtcRay,
        pub hit: RtcHit,
    }

    /// `struct RTCRayK` and `struct RTCHitK` for K = 4, 8, 16, SoA, aligned to 4K bytes.
    macro_rules! soa {
        ($ray:ident, $hit:ident, $rayhit:ident, $k:literal, $align:literal) => {
            /// `struct RTCRay` of this width, SoA.
            #[repr(C, align($align))]
            #[derive(Clone, Copy)]
            pub struct $ray {
                pub org_x: [f32; $k],
                pub org_y: [f32; $k],
                pub org_z: [f32; $k],
                pub tnear: [f32; $k],
                pub dir_x: [f32; $k],
                pub dir_y: [f32; $k],
                pub dir_z: [f32; $k],
                pub time: [f32; $k],
                pub tfar: [f32; $k],
                pub mask: [c_uint; $k],
                pub id: [c_uint; $k],
                pub flags: [c_uint; $k],
            }

            /// `struct RTCHit` of this width, SoA.
            #[repr(C, align($align))]
            #[derive(Clone, Copy)]
            pub struct $hit {
                pub ng_x: [f32; $k],
                pub ng_y: [f32; $k],
                pub ng_z: [f32; $k],
                pub u: [f32; $k],
                pub v: [f32; $k],
                pub prim_id: [c_uint; $k],
                pub geom_id: [c_uint; $k],
                pub inst_id: [[c_uint; $k]; 1],
            }

            /// `struct RTCRayHit` of this width.
            #[repr(C)]
            #[derive(Clone, Copy)]
            pub struct $rayhit {
                pub ray: $ray,
                pub hit: $hit,
            }
        };
    }
    soa!(RtcRay4, RtcHit4, RtcRayHit4, 4, 16);
    soa!(RtcRay8, RtcHit8, RtcRayHit8, 8, 32);
    soa!(RtcRay16, RtcHit16, RtcRayHit16, 16, 64);

    #[link(name = "embree3")]
    unsafe extern "C" {
        pub fn rtcNewDevice(config: *const c_char) -> RtcDevice;
        pub fn rtcReleaseDevice(device: RtcDevice);
        pub fn rtcGetDeviceError(device: RtcDevice) -> c_int;
        pub fn rtcGetDeviceProperty(device: RtcDevice, prop: c_int) -> isize;
        pub fn rtcNewScene(device: RtcDevice) -> RtcScene;
        pub fn rtcReleaseScene(scene: RtcScene);
        pub fn rtcSetSceneBuildQuality(scene: RtcScene, quality: c_int);
        pub fn rtcSetSceneFlags(scene: RtcScene, flags: c_int);
        pub fn rtcCommitScene(scene: RtcScene);
        pub fn rtcNewGeometry(device: RtcDevice, kind: c_int) -> RtcGeometry;
        pub fn rtcSetGeometryBuildQuality(geometry: RtcGeometry, quality: c_int);
        pub fn rtcSetNewGeometryBuffer(
            geometry: RtcGeometry,
            kind: c_int,
            slot: c_uint,
            format: c_int,
            byte_stride: usize,
            item_count: usize,
        ) -> *mut c_void;
        pub fn rtcCommitGeometry(geometry: RtcGeometry);
        pub fn rtcAttachGeometry(scene: RtcScene, geometry: RtcGeometry) -> c_uint;
        pub fn rtcReleaseGeometry(geometry: RtcGeometry);
        pub fn rtcIntersect1(scene: RtcScene, context: *mut RtcIntersectContext, rayhit: *mut RtcRayHit);
        pub fn rtcOccluded1(scene: RtcScene, context: *mut RtcIntersectContext, ray: *mut RtcRay);
        pub fn rtcIntersect4(
            valid: *const c_int,
            scene: RtcScene,
            context: *mut RtcIntersectContext,
            rayhit: *mut RtcRayHit4,
        );
        pub fn rtcIntersect8(
            valid: *const c_int,
            scene: RtcScene,
            context: *mut RtcIntersectContext,
            rayhit: *mut RtcRayHit8,
        );
        pub fn rtcIntersect16(
            valid: *const c_int,
            scene: RtcScene,
            context: *mut RtcIntersectContext,
            rayhit: *mut RtcRayHit16,
        );
        pub fn rtcOccluded4(valid: *const c_int, scene: RtcScene, context: *mut RtcIntersectContext, ray: *mut RtcRay4);
        pub fn rtcOccluded8(valid: *const c_int, scene: RtcScene, context: *mut RtcIntersectContext, ray: *mut RtcRay8);
        pub fn rtcOccluded16(
            valid: *const c_int,
            scene: RtcScene,
            context: *mut RtcIntersectContext,
            ray: *mut RtcRay16,
        );
    }
}

/// What went wrong in Embree.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EmbreeError {
    /// `rtcNewDevice` failed (an unsupported CPU, for example).
    #[error("cannot create the Embree device: {0}")]
    Device(String),
    /// An Embree call reported an error code.
    #[error("Embree {call} failed: {code}")]
    Call {
        /// The call.
        call: &'static str,
        /// `RTCError`, in words.
        code: String,
    },
    /// The mesh has more triangles or vertices than Embree's 32-bit ids hold.
    #[error("the mesh is too large for Embree ({0} triangles)")]
    TooLarge(usize),
}

/// The words for an `RTCError` code.
fn error_name(code: c_int) -> String {
    match code {
        0 => "no error".into(),
        1 => "unknown error".into(),
        2 => "invalid argument".into(),
        3 => "invalid operation".into(),
        4 => "out of memory".into(),
        5 => "unsupported CPU".into(),
        6 => "cancelled".into(),
        c => format!("error code {c}"),
    }
}

/// Embree's build quality (`RTCBuildQuality`) for the scene's BVH.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BuildQuality {
    /// Morton-code build, fastest to build (`RTC_BUILD_QUALITY_LOW`).
    Low,
    /// Binned SAH, Embree's default (`RTC_BUILD_QUALITY_MEDIUM`).
    Medium,
    /// SAH with spatial splits (`RTC_BUILD_QUALITY_HIGH`).
    High,
}

impl BuildQuality {
    fn code(self) -> c_int {
        match self {
            BuildQuality::Low => 0,
            BuildQuality::Medium => 1,
            BuildQuality::High => 2,
        }
    }

    /// The name in reports (`low`, `medium`, `high`).
    pub fn name(self) -> &'static str {
        match self {
            BuildQuality::Low => "low",
            BuildQuality::Medium => "medium",
            BuildQuality::High => "high",
        }
    }
}

/// The intersect context's coherence hint (`RTCIntersectContextFlags`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Coherence {
    /// `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`: the rays of a packet or stream are coherent
    /// (camera rays of neighbouring pixels, shadow rays to one light).
    Coherent,
    /// `RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT`: Embree's default.
    Incoherent,
}

/// `rtcInitIntersectContext` (a static inline of the header, written out here): the flag,
/// no filter, no instance.
fn context(coherence: Coherence) -> sys::RtcIntersectContext {
    sys::RtcIntersectContext {
        flags: match coherence {
            Coherence::Coherent => sys::CONTEXT_FLAG_COHERENT,
            Coherence::Incoherent => sys::CONTEXT_FLAG_INCOHERENT,
        },
        filter: None,
        inst_id: [sys::INVALID_GEOMETRY_ID],
    }
}

/// What the device supports (`rtcGetDeviceProperty`).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct DeviceInfo {
    /// `RTC_DEVICE_PROPERTY_VERSION`, e.g. 31305 for 3.13.5.
    pub version: i64,
    /// Packets of 4 traced natively (else emulated).
    pub native_ray4: bool,
    /// Packets of 8 traced natively (AVX/AVX2 kernels).
    pub native_ray8: bool,
    /// Packets of 16 traced natively (AVX-512 kernels).
    pub native_ray16: bool,
    /// `RTC_DEVICE_PROPERTY_TASKING_SYSTEM`: 0 internal, 1 TBB, 2 PPL.
    pub tasking_system: i64,
}

impl DeviceInfo {
    /// `3.13.5` from the version number.
    pub fn version_string(&self) -> String {
        format!("{}.{}.{}", self.version / 10000, self.version / 100 % 100, self.version % 100)
    }
}

/// An Embree device (`RTCDevice`), released on drop.
#[derive(Debug)]
pub struct Device {
    raw: NonNull<c_void>,
}

// SAFETY: an RTCDevice is a reference-counted object that Embree's API lets any thread use
// (scene creation and queries are thread-safe; Embree documents that calls on one device may
// come from any thread).
unsafe impl Send for Device {}
// SAFETY: as for Send; the only `&self` methods read device properties.
unsafe impl Sync for Device {}

impl Device {
    /// A device with `threads` build threads (`threads=N` in the configuration string), or
    /// Embree's default (all cores) for `None`.
    pub fn new(threads: Option<usize>) -> Result<Device, EmbreeError> {
        let config = match threads {
            Some(n) => format!("threads={n}"),
            None => String::new(),
        };
        let config = CString::new(config).map_err(|e| EmbreeError::Device(e.to_string()))?;
        // SAFETY: `config` is a NUL-terminated string that outlives the call.
        let raw = unsafe { sys::rtcNewDevice(config.as_ptr()) };
        match NonNull::new(raw) {
            Some(raw) => Ok(Device { raw }),
            None => {
                // SAFETY: a null device asks for the error of the failed device creation.
                let code = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
                Err(EmbreeError::Device(error_name(code)))
            }
        }
    }

    /// The device's version and native packet widths.
    pub fn info(&self) -> DeviceInfo {
        // SAFETY: `self.raw` is a live device; the properties are plain integer queries.
        let prop = |p: c_int| unsafe { sys::rtcGetDeviceProperty(self.raw.as_ptr(), p) } as i64;
        DeviceInfo {
            version: prop(0),
            native_ray4: prop(32) != 0,
            native_ray8: prop(33) != 0,
            native_ray16: prop(34) != 0,
            tasking_system: prop(128),
        }
    }

    /// The device's pending error, as a result.
    fn check(&self, call: &'static str) -> Result<(), EmbreeError> {
        // SAFETY: `self.raw` is a live device.
        let code = unsafe { sys::rtcGetDeviceError(self.raw.as_ptr()) };
        if code == 0 { Ok(()) } else { Err(EmbreeError::Call { call, code: error_name(code) }) }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the device; scenes hold references of their own.
        unsafe { sys::rtcReleaseDevice(self.raw.as_ptr()) }
    }
}

/// A committed Embree scene holding one triangle mesh, released on drop. Queries take
/// `&self` and may run on many threads at once.
#[derive(Debug)]
pub struct EmbreeScene {
    raw: NonNull<c_void>,
}

// SAFETY: a committed RTCScene is immutable; Embree documents rtcIntersect*/rtcOccluded* on a
// committed scene as thread-safe, and the scene keeps its device alive by reference count.
unsafe impl Send for EmbreeScene {}
// SAFETY: as for Send: every `&self` method is a query on the committed scene.
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Builds the BVH of the triangles `triangles` (indices into `positions`) at `quality`,
    /// with the mesh copied into Embree's own (padded) buffers. Triangle `i` is Embree's
    /// `primID` `i`.
    pub fn build(
        device: &Device,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        quality: BuildQuality,
    ) -> Result<EmbreeScene, EmbreeError> {
        if u32::try_from(triangles.len()).is_err() || u32::try_from(positions.len()).is_err() {
            return Err(EmbreeError::TooLarge(triangles.len()));
        }
        if let Some(bad) = triangles.iter().flatten().find(|&&i| i as usize >= positions.len()) {
            return Err(EmbreeError::Call {
                call: "rtcSetNewGeometryBuffer",
                code: format!("vertex index {bad} out of range"),
            });
        }
        // SAFETY: `device` is live; a null scene is checked below.
        let scene = unsafe { sys::rtcNewScene(device.raw.as_ptr()) };
        let scene = NonNull::new(scene).ok_or_else(|| {
            device.check("rtcNewScene").err().unwrap_or(EmbreeError::Device("rtcNewScene returned null".into()))
        })?;
        // From here the scene is released by `EmbreeScene`'s drop on every path.
        let out = EmbreeScene { raw: scene };
        // SAFETY: `scene` is a live scene; the quality and flags are valid enum values.
        unsafe {
            sys::rtcSetSceneFlags(scene.as_ptr(), sys::SCENE_FLAG_NONE);
            sys::rtcSetSceneBuildQuality(scene.as_ptr(), quality.code());
        }
        if !triangles.is_empty() {
            // SAFETY: `device` is live; the geometry is checked for null below.
            let geometry = unsafe { sys::rtcNewGeometry(device.raw.as_ptr(), sys::GEOMETRY_TYPE_TRIANGLE) };
            if geometry.is_null() {
                return Err(device
                    .check("rtcNewGeometry")
                    .err()
                    .unwrap_or(EmbreeError::Call { call: "rtcNewGeometry", code: "null geometry".into() }));
            }
            // SAFETY: `geometry` is live. Embree allocates each buffer for `count` items of
            // `stride` bytes (over-allocated for 16-byte loads of the last vertex) and returns
            // it, or null after recording an error; we write exactly `count * stride` bytes
            // into each, element types matching the declared formats (FLOAT3 = three f32,
            // UINT3 = three u32). The geometry is committed, attached (the scene takes its own
            // reference) and our reference released, on every path.
            let filled = unsafe {
                sys::rtcSetGeometryBuildQuality(geometry, quality.code());
                let vertices = sys::rtcSetNewGeometryBuffer(
                    geometry,
                    sys::BUFFER_TYPE_VERTEX,
                    0,
                    sys::FORMAT_FLOAT3,
                    12,
                    positions.len(),
                ) as *mut [f32; 3];
                let indices = sys::rtcSetNewGeometryBuffer(
                    geometry,
                    sys::BUFFER_TYPE_INDEX,
                    0,
                    sys::FORMAT_UINT3,
                    12,
                    triangles.len(),
                ) as *mut [u32; 3];
                let ok = !vertices.is_null() && !indices.is_null();
                if ok {
                    for (i, p) in positions.iter().enumerate() {
                        vertices.add(i).write(p.to_array());
                    }
                    for (i, t) in triangles.iter().enumerate() {
                        indices.add(i).write(*t);
                    }
                    sys::rtcCommitGeometry(geometry);
                    sys::rtcAttachGeometry(scene.as_ptr(), geometry);
                }
                sys::rtcReleaseGeometry(geometry);
                ok
            };
            device.check("rtcSetNewGeometryBuffer")?;
            if !filled {
                return Err(EmbreeError::Call { call: "rtcSetNewGeometryBuffer", code: "null buffer".into() });
            }
        }
        // SAFETY: `scene` is live and every attached geometry is committed.
        unsafe { sys::rtcCommitScene(scene.as_ptr()) };
        device.check("rtcCommitScene")?;
        Ok(out)
    }

    /// The closest hit of `ray` in `[t_min, t_max]` (`rtcIntersect1`; a negative `t_min`
    /// as [`EmbreeRay`] moves it).
    #[inline]
    pub fn intersect(&self, ray: &Ray, coherence: Coherence) -> Option<Hit> {
        let e = EmbreeRay::new(ray)?;
        let mut rayhit = sys::RtcRayHit { ray: e.rtc(ray), hit: sys::RtcHit::default() };
        rayhit.hit.geom_id = sys::INVALID_GEOMETRY_ID;
        rayhit.hit.inst_id = [sys::INVALID_GEOMETRY_ID];
        let mut ctx = context(coherence);
        // SAFETY: the scene is committed; `ctx` and `rayhit` are valid, aligned and live for
        // the call (RtcRayHit is 16-byte aligned by its fields' `repr(align(16))`).
        unsafe { sys::rtcIntersect1(self.raw.as_ptr(), &mut ctx, &mut rayhit) };
        (rayhit.hit.geom_id != sys::INVALID_GEOMETRY_ID).then_some(Hit {
            t: rayhit.ray.tfar + e.shift,
            u: rayhit.hit.u,
            v: rayhit.hit.v,
            prim: rayhit.hit.prim_id,
        })
    }

    /// Whether anything blocks `ray` in `[t_min, t_max]` (`rtcOccluded1`).
    #[inline]
    pub fn occluded(&self, ray: &Ray, coherence: Coherence) -> bool {
        let Some(e) = EmbreeRay::new(ray) else { return false };
        let mut r = e.rtc(ray);
        let mut ctx = context(coherence);
        // SAFETY: as in `intersect`; RtcRay is 16-byte aligned.
        unsafe { sys::rtcOccluded1(self.raw.as_ptr(), &mut ctx, &mut r) };
        r.tfar == f32::NEG_INFINITY
    }

    /// Traces the active lanes of `packet` for their closest hits (`rtcIntersect4/8/16`);
    /// read them with [`Packet::hit`].
    #[inline]
    pub fn intersect_packet<P: Packet>(&self, packet: &mut P, coherence: Coherence) {
        packet.intersect_in(self, coherence);
    }

    /// Traces the active lanes of `packet` for any hit (`rtcOccluded4/8/16`); read them with
    /// [`Packet::occluded`].
    #[inline]
    pub fn occluded_packet<P: Packet>(&self, packet: &mut P, coherence: Coherence) {
        packet.occluded_in(self, coherence);
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: we own the one application reference to the scene.
        unsafe { sys::rtcReleaseScene(self.raw.as_ptr()) }
    }
}

/// Embree's `FLT_LARGE`: `RTCRay::valid()` asserts that every origin and direction
/// component is within it.
const FLT_LARGE: f32 = 1.844e18;

/// Our ray in the form Embree takes (see the module documentation): `tnear >= 0`, the origin
/// moved back by a negative `t_min`, and the `shift` to add to Embree's `t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmbreeRay {
    /// The origin: ours, or `o + t_min * d` for a negative `t_min`.
    pub org: [f32; 3],
    /// `t_min`, or 0 for a negative `t_min`.
    pub tnear: f32,
    /// `t_max`, or `t_max - t_min` for a negative `t_min`.
    pub tfar: f32,
    /// What to add to Embree's `t` for ours: 0, or the negative `t_min`.
    pub shift: f32,
}

impl EmbreeRay {
    /// `ray` in Embree's form, or `None` when Embree cannot take it (the ray is then a miss).
    pub fn new(ray: &Ray) -> Option<EmbreeRay> {
        let (t_min, t_max) = (ray.t_min, ray.t_max);
        if t_min.is_nan() || t_max.is_nan() || t_min > t_max {
            return None;
        }
        let out = if t_min < 0.0 {
            let org = ray.origin + t_min * ray.dir;
            EmbreeRay { org: org.to_array(), tnear: 0.0, tfar: t_max - t_min, shift: t_min }
        } else {
            EmbreeRay { org: ray.origin.to_array(), tnear: t_min, tfar: t_max, shift: 0.0 }
        };
        let within = |v: [f32; 3]| v.iter().all(|c| c.abs() <= FLT_LARGE);
        (within(out.org) && within(ray.dir.to_array()) && !out.tfar.is_nan()).then_some(out)
    }

    /// The `RTCRay`, every mask bit set.
    #[inline]
    fn rtc(&self, ray: &Ray) -> sys::RtcRay {
        sys::RtcRay {
            org: self.org,
            tnear: self.tnear,
            dir: ray.dir.to_array(),
            time: 0.0,
            tfar: self.tfar,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }
}

/// A packet of `WIDTH` rays for Embree's packet queries: rays set lane by lane, inactive
/// lanes left out (the `valid` mask), results read lane by lane.
pub trait Packet: Default + Send {
    /// Rays in the packet (4, 8 or 16).
    const WIDTH: usize;
    /// Makes every lane inactive.
    fn clear(&mut self);
    /// Puts `ray` in `lane` and makes the lane active (a negative `t_min` moved as
    /// [`EmbreeRay`] does; a ray Embree cannot take is a miss). Panics if `lane >= WIDTH`.
    fn set(&mut self, lane: usize, ray: &Ray);
    /// Clears the packet, then puts `rays[i]` in lane `i` (see [`Packet::set`]); the lanes
    /// after them stay inactive. Panics if there are more than `WIDTH` rays.
    fn load(&mut self, rays: &[Ray]) {
        self.clear();
        for (lane, ray) in rays.iter().enumerate() {
            self.set(lane, ray);
        }
    }
    /// Whether `lane` is active.
    fn active(&self, lane: usize) -> bool;
    /// The closest hit of `lane` after [`EmbreeScene::intersect_packet`] (`None` for a miss
    /// or an inactive lane).
    fn hit(&self, lane: usize) -> Option<Hit>;
    /// Whether `lane` was blocked, after [`EmbreeScene::occluded_packet`] (`false` for
    /// inactive lanes).
    fn occluded(&self, lane: usize) -> bool;
    /// `rtcIntersectK` on the active lanes.
    #[doc(hidden)]
    fn intersect_in(&mut self, scene: &EmbreeScene, coherence: Coherence);
    /// `rtcOccludedK` on the active lanes.
    #[doc(hidden)]
    fn occluded_in(&mut self, scene: &EmbreeScene, coherence: Coherence);
}

macro_rules! packet {
    ($(#[$doc:meta])* $name:ident, $rayhit:ident, $k:literal, $isect:ident, $occl:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy)]
        pub struct $name {
            /// Embree's mask: lanes set with a ray Embree can take.
            valid: [c_int; $k],
            /// Lanes set (with any ray).
            used: [bool; $k],
            /// Per lane, what to add to Embree's `t` ([`EmbreeRay::shift`]).
            shift: [f32; $k],
            rayhit: sys::$rayhit,
        }

        impl Default for $name {
            fn default() -> Self {
                // SAFETY: every field of the SoA structs is an array of f32 or u32, for which
                // all-zero bytes are valid values.
                let rayhit: sys::$rayhit = unsafe { std::mem::zeroed() };
                $name { valid: [0; $k], used: [false; $k], shift: [0.0; $k], rayhit }
            }
        }

        impl std::fmt::Debug for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.debug_struct(stringify!($name)).field("valid", &self.valid).finish_non_exhaustive()
            }
        }

        impl Packet for $name {
            const WIDTH: usize = $k;

            #[inline]
            fn clear(&mut self) {
                self.valid = [0; $k];
                self.used = [false; $k];
            }

            #[inline]
            fn set(&mut self, lane: usize, ray: &Ray) {
                self.used[lane] = true;
                // A ray Embree cannot take stays out of its mask: a miss.
                let Some(e) = EmbreeRay::new(ray) else {
                    self.valid[lane] = 0;
                    return;
                };
                self.shift[lane] = e.shift;
                let r = &mut self.rayhit.ray;
                [r.org_x[lane], r.org_y[lane], r.org_z[lane]] = e.org;
                r.tnear[lane] = e.tnear;
                r.dir_x[lane] = ray.dir.x;
                r.dir_y[lane] = ray.dir.y;
                r.dir_z[lane] = ray.dir.z;
                r.time[lane] = 0.0;
                r.tfar[lane] = e.tfar;
                r.mask[lane] = u32::MAX;
                r.id[lane] = lane as u32;
                r.flags[lane] = 0;
                let h = &mut self.rayhit.hit;
                h.geom_id[lane] = sys::INVALID_GEOMETRY_ID;
                h.inst_id[0][lane] = sys::INVALID_GEOMETRY_ID;
                self.valid[lane] = -1;
            }

            #[inline]
            fn active(&self, lane: usize) -> bool {
                self.used[lane]
            }

            #[inline]
            fn hit(&self, lane: usize) -> Option<Hit> {
                let h = &self.rayhit.hit;
                (self.valid[lane] != 0 && h.geom_id[lane] != sys::INVALID_GEOMETRY_ID).then(|| Hit {
                    t: self.rayhit.ray.tfar[lane] + self.shift[lane],
                    u: h.u[lane],
                    v: h.v[lane],
                    prim: h.prim_id[lane],
                })
            }

            #[inline]
            fn occluded(&self, lane: usize) -> bool {
                self.valid[lane] != 0 && self.rayhit.ray.tfar[lane] == f32::NEG_INFINITY
            }

            #[inline]
            fn intersect_in(&mut self, scene: &EmbreeScene, coherence: Coherence) {
                let mut ctx = context(coherence);
                // SAFETY: the scene is committed; `valid` has WIDTH ints; `rayhit` has the
                // header's layout and alignment (checked in the tests) and every active lane
                // was filled by `set`; all live for the call.
                unsafe { sys::$isect(self.valid.as_ptr(), scene.raw.as_ptr(), &mut ctx, &mut self.rayhit) };
            }

            #[inline]
            fn occluded_in(&mut self, scene: &EmbreeScene, coherence: Coherence) {
                let mut ctx = context(coherence);
                // SAFETY: as in `intersect_in`; the ray part is the first field of the
                // `#[repr(C)]` ray-hit struct, so it is a valid `RTCRayK` with its alignment.
                unsafe { sys::$occl(self.valid.as_ptr(), scene.raw.as_ptr(), &mut ctx, &mut self.rayhit.ray) };
            }
        }
    };
}

packet!(
    /// Four rays (`RTCRayHit4`, 16-byte aligned): a 2x2 pixel block.
    Packet4, RtcRayHit4, 4, rtcIntersect4, rtcOccluded4
);
packet!(
    /// Eight rays (`RTCRayHit8`, 32-byte aligned): a 4x2 pixel block.
    Packet8, RtcRayHit8, 8, rtcIntersect8, rtcOccluded8
);
packet!(
    /// Sixteen rays (`RTCRayHit16`, 64-byte aligned): a 4x4 pixel block.
    Packet16, RtcRayHit16, 16, rtcIntersect16, rtcOccluded16
);

/// Embree's version string as the library reports it (`RTC_DEVICE_PROPERTY_VERSION`), or
/// `None` when no device can be made.
pub fn version() -> Option<String> {
    Device::new(Some(1)).ok().map(|d| d.info().version_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    /// Sizes, alignments and offsets that gcc gives for the structs of Debian's
    /// `embree3/rtcore.h` (3.13.5, `RTC_MAX_INSTANCE_LEVEL_COUNT` 1).
    #[test]
    fn layouts_match_the_header() {
        assert_eq!((size_of::<sys::RtcRay>(), align_of::<sys::RtcRay>()), (48, 16));
        assert_eq!((size_of::<sys::RtcHit>(), align_of::<sys::RtcHit>()), (32, 16));
        assert_eq!((size_of::<sys::RtcRayHit>(), offset_of!(sys::RtcRayHit, hit)), (80, 48));
        assert_eq!((size_of::<sys::RtcRay4>(), align_of::<sys::RtcRay4>()), (192, 16));
        assert_eq!((size_of::<sys::RtcHit4>(), align_of::<sys::RtcHit4>()), (128, 16));
        assert_eq!((size_of::<sys::RtcRayHit4>(), offset_of!(sys::RtcRayHit4, hit)), (320, 192));
        assert_eq!((size_of::<sys::RtcRay8>(), align_of::<sys::RtcRay8>()), (384, 32));
        assert_eq!((size_of::<sys::RtcHit8>(), align_of::<sys::RtcHit8>()), (256, 32));
        assert_eq!((size_of::<sys::RtcRayHit8>(), offset_of!(sys::RtcRayHit8, hit)), (640, 384));
        assert_eq!((size_of::<sys::RtcRay16>(), align_of::<sys::RtcRay16>()), (768, 64));
        assert_eq!((size_of::<sys::RtcHit16>(), align_of::<sys::RtcHit16>()), (512, 64));
        assert_eq!((size_of::<sys::RtcRayHit16>(), offset_of!(sys::RtcRayHit16, hit)), (1280, 768));
        assert_eq!((size_of::<sys::RtcIntersectContext>(), align_of::<sys::RtcIntersectContext>()), (24, 8));
        assert_eq!(offset_of!(sys::RtcRay, tfar), 32);
        assert_eq!(offset_of!(sys::RtcHit, prim_id), 20);
        assert_eq!(offset_of!(sys::RtcRay16, tfar), 8 * 64);
    }

    fn quad() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        (p, vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn single_rays_and_packets_hit_the_quad() {
        let device = Device::new(Some(1)).unwrap();
        let info = device.info();
        assert!(info.version >= 30000, "{info:?}");
        let (p, t) = quad();
        for quality in [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High] {
            let scene = EmbreeScene::build(&device, &p, &t, quality).unwrap();
            let ray = Ray::new(Vec3::new(0.5, -0.5, 2.0), Vec3::new(0.0, 0.0, -2.0), 0.0, f32::INFINITY);
            let hit = scene.intersect(&ray, Coherence::Incoherent).unwrap();
            assert_eq!(hit.prim, 0);
            assert!((hit.t - 1.0).abs() < 1e-6);
            // u, v weight the second and third vertex, as ours do.
            let point = p[0] + hit.u * (p[1] - p[0]) + hit.v * (p[2] - p[0]);
            assert!((point - ray.at(hit.t)).length() < 1e-5);
            assert!(scene.occluded(&ray, Coherence::Coherent));
            let short = Ray { t_max: 0.4, ..ray };
            assert!(!scene.occluded(&short, Coherence::Coherent));
            assert!(scene.intersect(&short, Coherence::Coherent).is_none());

            let mut packet = Packet16::default();
            for lane in [0, 5, 15] {
                let o = Vec3::new(-0.5 + 0.05 * lane as f32, 0.5, 2.0);
                packet.set(lane, &Ray::new(o, Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY));
            }
            packet.set(7, &Ray::new(Vec3::new(5.0, 5.0, 2.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY));
            scene.intersect_packet(&mut packet, Coherence::Coherent);
            for lane in [0, 5, 15] {
                let h = packet.hit(lane).unwrap();
                assert_eq!(h.prim, 1);
                assert!((h.t - 2.0).abs() < 1e-6);
            }
            assert!(packet.hit(7).is_none() && packet.hit(1).is_none());
            let mut packet = Packet4::default();
            packet.set(2, &ray);
            packet.set(3, &short);
            scene.occluded_packet(&mut packet, Coherence::Incoherent);
            assert!(packet.occluded(2) && !packet.occluded(3) && !packet.occluded(0));
        }
    }

    /// A negative `t_min` (which Embree's own assertion would abort on) finds hits behind the
    /// origin, single rays and packets alike; rays Embree cannot take are misses, not aborts.
    #[test]
    fn negative_t_min_and_rays_embree_cannot_take() {
        let device = Device::new(Some(1)).unwrap();
        let (p, t) = quad();
        let scene = EmbreeScene::build(&device, &p, &t, BuildQuality::High).unwrap();
        let tree = kdtree::KdTree::build(&p, &t, &kdtree::BuildConfig::default()).unwrap();
        // The quad (z = 0) lies at t = -1 behind the origin, at t = 1 in front of the other.
        let below = |t_min: f32, t_max: f32| Ray::new(Vec3::new(0.5, -0.5, -1.0), -Vec3::Z, t_min, t_max);
        let above = Ray::new(Vec3::new(-0.25, 0.5, 1.0), -Vec3::Z, -5.0, 3.0);
        let behind = below(-2.0, f32::INFINITY);
        // Embree's `t` of a moved ray is within a few ulps of `|t_min|` of the exact one (the
        // module's conventions); how many depends on the kernel Embree picked for this CPU
        // (one CI machine gave 0.9999995 for 1.0). Ours is exact.
        let near = |t: f32, want: f32, t_min: f32| (t - want).abs() <= 8.0 * f32::EPSILON * t_min.abs().max(1.0);
        let hit = scene.intersect(&behind, Coherence::Coherent).unwrap();
        assert!(hit.prim == 0 && near(hit.t, -1.0, -2.0), "{hit:?}");
        assert_eq!(tree.intersect(&behind).map(|h| (h.prim, h.t)), Some((0, -1.0)));
        assert!(scene.occluded(&behind, Coherence::Coherent));
        let hit = scene.intersect(&above, Coherence::Incoherent).unwrap();
        assert!(hit.prim == 1 && near(hit.t, 1.0, -5.0), "{hit:?}");
        let short = [below(-0.5, f32::INFINITY), below(-3.0, -1.5), below(0.0, 10.0)];
        for r in &short {
            assert!(scene.intersect(r, Coherence::Coherent).is_none(), "{r:?}");
            assert!(!scene.occluded(r, Coherence::Coherent), "{r:?}");
            assert!(tree.intersect(r).is_none(), "{r:?}");
        }
        // NaN intervals, t_min = -inf and origins beyond FLT_LARGE: misses, not aborts.
        let cannot = [
            below(f32::NAN, 1.0),
            below(f32::NEG_INFINITY, 1.0),
            Ray::new(Vec3::new(0.0, 0.0, 1e19), -Vec3::Z, 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.0, 0.0, 1e18), -Vec3::Z, -1e18, f32::INFINITY),
        ];
        for r in &cannot {
            assert!(EmbreeRay::new(r).is_none(), "{r:?}");
            assert!(scene.intersect(r, Coherence::Coherent).is_none() && !scene.occluded(r, Coherence::Coherent));
        }
        assert_eq!(
            EmbreeRay::new(&behind).map(|e| (e.org, e.tnear, e.tfar, e.shift)),
            Some(([0.5, -0.5, 1.0], 0.0, f32::INFINITY, -2.0))
        );
        // Packets: the same answers lane by lane; every set lane is active.
        // Lane 7: the quad at t = -1 from a negative interval that ends before 0.
        let lanes = [behind, above, short[0], short[1], cannot[0], cannot[1], cannot[2], below(-1.5, -0.5)];
        let mut packet = Packet8::default();
        packet.load(&lanes);
        scene.intersect_packet(&mut packet, Coherence::Coherent);
        for (lane, r) in lanes.iter().enumerate() {
            assert!(packet.active(lane));
            // Embree's packet and single-ray kernels may round a moved ray's `t` apart.
            let (single, lane_hit) = (scene.intersect(r, Coherence::Coherent), packet.hit(lane));
            assert_eq!(lane_hit.map(|h| h.prim), single.map(|h| h.prim), "lane {lane}");
            if let (Some(a), Some(b)) = (lane_hit, single) {
                assert!(near(a.t, b.t, r.t_min), "lane {lane}: {a:?} against {b:?}");
            }
        }
        let hit = packet.hit(7).unwrap();
        assert!(hit.prim == 0 && near(hit.t, -1.0, -1.5), "{hit:?}");
        // The same rays again: the query above shortened each lane's `tfar` to its hit, and
        // whether a hit at exactly `tfar` blocks depends on the kernel Embree picked.
        packet.load(&lanes);
        scene.occluded_packet(&mut packet, Coherence::Coherent);
        let blocked: Vec<bool> = (0..8).map(|lane| packet.occluded(lane)).collect();
        assert_eq!(blocked, [true, true, false, false, false, false, false, true]);
    }

    #[test]
    fn empty_and_bad_meshes() {
        let device = Device::new(Some(1)).unwrap();
        let scene = EmbreeScene::build(&device, &[], &[], BuildQuality::High).unwrap();
        let ray = Ray::new(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY);
        assert!(scene.intersect(&ray, Coherence::Coherent).is_none());
        let (p, _) = quad();
        assert!(EmbreeScene::build(&device, &p, &[[0, 1, 9]], BuildQuality::High).is_err());
        // A degenerate triangle is kept (ids do not shift) and never hit.
        let scene = EmbreeScene::build(&device, &p, &[[0, 0, 1], [0, 1, 2]], BuildQuality::Medium).unwrap();
        let down = Ray::new(Vec3::new(0.5, -0.5, 1.0), Vec3::new(0.0, 0.0, -1.0), 0.0, f32::INFINITY);
        assert_eq!(scene.intersect(&down, Coherence::Coherent).map(|h| h.prim), Some(1));
    }
}
