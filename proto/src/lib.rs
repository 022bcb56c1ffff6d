//! The laparo gRPC contract.
//!
//! laparo is a networked training server for laparoscopic liver surgery: a
//! deformable liver, instrument contact and reaction forces after Forest,
//! Delingette and Ayache (2004). This crate is what the server and its clients
//! share:
//!
//! - [`v1`]: the package `laparo.v1`, generated from `proto/laparo/v1/*.proto`:
//!   the prost messages, and the tonic client and server of each service
//!   (`Scenes`, `Sessions`, `Station`, `Observe`, `Recordings`).
//! - [`FILE_DESCRIPTOR_SET`]: the encoded descriptors of those files (with their
//!   imports and comments), for gRPC reflection and MCAP schemas.
//! - [`force`]: the force of a local model (eq. 8), the combination of the tip and
//!   shaft forces (eq. 9, derived again) and the axial/torque split — pure functions
//!   that server and clients must compute alike.
//! - [`text`]: text from files and clients made safe to print (control characters
//!   and terminal escapes written as escapes), for the server's messages and the
//!   clients' tables alike.
//!
//! Units on the wire are SI (m, kg, s, N, Pa, N·m); positions and directions are
//! in the world frame of the scene, in metres. The `.proto` files are the
//! reference: every field there states its unit and frame.

pub mod force;
pub mod text;

/// The package `laparo.v1`: messages, enums, and the tonic `*_client` and
/// `*_server` modules of each service.
pub mod v1 {
    // A oneof holds its messages inline, as prost generates it, so an
    // `InstrumentState` makes its `Kind` enum large; boxing it would cost an
    // allocation for every message on the wire.
    #![allow(clippy::large_enum_variant)]

    tonic::include_proto!("laparo.v1");
}

/// The encoded `google.protobuf.FileDescriptorSet` of the contract: every file of
/// `laparo.v1` and the well-known types it imports, with source comments.
pub const FILE_DESCRIPTOR_SET: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/laparo_descriptor.bin"));
