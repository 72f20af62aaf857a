//! The few Embree 4.4 declarations the peer needs, written by hand against the 4.4 headers
//! (`embree4/rtcore_{device,scene,geometry,buffer,ray,common}.h`).
//!
//! Layout notes (a mismatch silently corrupts results; the harness's agreement check catches it):
//! * `RTCRay` is 48 bytes (org, tnear, dir, time, tfar, mask, id, flags), 16-byte aligned.
//! * `RTCHit` is Ng(3), u, v, primID, geomID, instID[RTC_MAX_INSTANCE_LEVEL_COUNT] and, since 4.3
//!   when built with instance arrays (the default), instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT].
//!   Those trailing arrays are the part that differs between versions/builds, so the structs
//!   below end in generous zeroed padding: every field we read sits before them at a fixed
//!   offset, and Embree may write as many trailing instance ids as its build has.
//! * `RTCRay16` is 12 arrays of 16 lanes (768 bytes); `RTCHit16` follows it in `RTCRayHit16`
//!   with Ng_x..geomID as 7 arrays of 16 lanes, then the instance-id arrays (padded here).
//! * `RTCIntersectArguments` / `RTCOccludedArguments`: flags, feature_mask, context*, filter*,
//!   intersect*/occluded*, and `minWidthDistanceFactor` only when built with RTC_MIN_WIDTH;
//!   we always provide that float (zero) plus padding, which is correct in both cases.
#![allow(non_camel_case_types, non_snake_case, dead_code)]

use std::os::raw::{c_char, c_int, c_uint, c_void};

pub type RTCDevice = *mut c_void;
pub type RTCScene = *mut c_void;
pub type RTCGeometry = *mut c_void;

pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
pub const RTC_BUILD_QUALITY_LOW: c_uint = 0;
pub const RTC_BUILD_QUALITY_MEDIUM: c_uint = 1;
pub const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
pub const RTC_SCENE_FLAG_NONE: c_uint = 0;
pub const RTC_RAY_QUERY_FLAG_INCOHERENT: c_uint = 0;
pub const RTC_RAY_QUERY_FLAG_COHERENT: c_uint = 1;
pub const RTC_FEATURE_FLAG_ALL: c_uint = 0xffff_ffff;
pub const RTC_INVALID_GEOMETRY_ID: c_uint = 0xffff_ffff;

pub const RTC_DEVICE_PROPERTY_VERSION: c_uint = 0;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED: c_uint = 32;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED: c_uint = 33;
pub const RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED: c_uint = 34;
pub const RTC_DEVICE_PROPERTY_TASKING_SYSTEM: c_uint = 128;

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
pub struct RTCRay {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: c_uint,
    pub id: c_uint,
    pub flags: c_uint,
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
pub struct RTCHit {
    pub Ng_x: f32,
    pub Ng_y: f32,
    pub Ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub primID: c_uint,
    pub geomID: c_uint,
    /// instID[L] then (4.3+) instPrimID[L]; padded for any L up to 24.
    pub inst: [c_uint; 49],
}

#[repr(C)]
#[derive(Clone, Copy)]
pub struct RTCRayHit {
    pub ray: RTCRay,
    pub hit: RTCHit,
}

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct RTCRay16 {
    pub org_x: [f32; 16],
    pub org_y: [f32; 16],
    pub org_z: [f32; 16],
    pub tnear: [f32; 16],
    pub dir_x: [f32; 16],
    pub dir_y: [f32; 16],
    pub dir_z: [f32; 16],
    pub time: [f32; 16],
    pub tfar: [f32; 16],
    pub mask: [c_uint; 16],
    pub id: [c_uint; 16],
    pub flags: [c_uint; 16],
}

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct RTCHit16 {
    pub Ng_x: [f32; 16],
    pub Ng_y: [f32; 16],
    pub Ng_z: [f32; 16],
    pub u: [f32; 16],
    pub v: [f32; 16],
    pub primID: [c_uint; 16],
    pub geomID: [c_uint; 16],
    /// instID[L][16] then (4.3+) instPrimID[L][16]; padded for any L up to 8.
    pub inst: [[c_uint; 16]; 16],
}

#[repr(C)]
#[derive(Clone, Copy)]
pub struct RTCRayHit16 {
    pub ray: RTCRay16,
    pub hit: RTCHit16,
}

#[repr(C, align(64))]
#[derive(Clone, Copy)]
pub struct Valid16(pub [c_int; 16]);

/// `RTCIntersectArguments` and `RTCOccludedArguments` share this layout.
#[repr(C)]
pub struct RTCQueryArguments {
    pub flags: c_uint,
    pub feature_mask: c_uint,
    pub context: *mut c_void,
    pub filter: *mut c_void,
    pub callback: *mut c_void,
    pub minWidthDistanceFactor: f32,
    pub _pad: [u32; 15],
}

impl RTCQueryArguments {
    /// What `rtcInitIntersectArguments` / `rtcInitOccludedArguments` set, with the given flags.
    pub fn new(flags: c_uint) -> Self {
        Self {
            flags,
            feature_mask: RTC_FEATURE_FLAG_ALL,
            context: std::ptr::null_mut(), // Embree then uses a default ray-query context
            filter: std::ptr::null_mut(),
            callback: std::ptr::null_mut(),
            minWidthDistanceFactor: 0.0,
            _pad: [0; 15],
        }
    }
}

pub type RTCErrorFunction =
    unsafe extern "C" fn(user: *mut c_void, code: c_uint, message: *const c_char);

extern "C" {
    pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
    pub fn rtcReleaseDevice(device: RTCDevice);
    pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
    pub fn rtcGetDeviceProperty(device: RTCDevice, prop: c_uint) -> isize;
    pub fn rtcSetDeviceErrorFunction(device: RTCDevice, f: RTCErrorFunction, user: *mut c_void);

    pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
    pub fn rtcReleaseScene(scene: RTCScene);
    pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
    pub fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
    pub fn rtcCommitScene(scene: RTCScene);
    pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;

    pub fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
    pub fn rtcReleaseGeometry(geometry: RTCGeometry);
    pub fn rtcCommitGeometry(geometry: RTCGeometry);
    pub fn rtcSetGeometryBuildQuality(geometry: RTCGeometry, quality: c_uint);
    pub fn rtcSetSharedGeometryBuffer(
        geometry: RTCGeometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        ptr: *const c_void,
        byte_offset: usize,
        byte_stride: usize,
        item_count: usize,
    );

    pub fn rtcIntersect1(scene: RTCScene, rayhit: *mut RTCRayHit, args: *mut RTCQueryArguments);
    pub fn rtcOccluded1(scene: RTCScene, ray: *mut RTCRay, args: *mut RTCQueryArguments);
    pub fn rtcIntersect16(
        valid: *const Valid16,
        scene: RTCScene,
        rayhit: *mut RTCRayHit16,
        args: *mut RTCQueryArguments,
    );
    pub fn rtcOccluded16(
        valid: *const Valid16,
        scene: RTCScene,
        ray: *mut RTCRay16,
        args: *mut RTCQueryArguments,
    );
}

// Offsets every reader of the structs relies on (checked at compile time).
const _: () = {
    assert!(std::mem::size_of::<RTCRay>() == 48);
    assert!(std::mem::offset_of!(RTCRayHit, hit) == 48);
    assert!(std::mem::offset_of!(RTCHit, u) == 12);
    assert!(std::mem::offset_of!(RTCHit, primID) == 20);
    assert!(std::mem::offset_of!(RTCHit, geomID) == 24);
    assert!(std::mem::size_of::<RTCRay16>() == 768);
    assert!(std::mem::offset_of!(RTCRayHit16, hit) == 768);
    assert!(std::mem::offset_of!(RTCHit16, primID) == 5 * 64);
    assert!(std::mem::offset_of!(RTCHit16, geomID) == 6 * 64);
    assert!(std::mem::offset_of!(RTCQueryArguments, context) == 8);
    assert!(std::mem::offset_of!(RTCQueryArguments, minWidthDistanceFactor) == 32);
};
