//! The contract as other languages see it: the exported descriptor set (what gRPC
//! reflection serves) and the wire encoding of the generated messages.

use std::collections::BTreeSet;

use laparo_proto::FILE_DESCRIPTOR_SET;
use laparo_proto::v1::{
    self, ContactState, DevicePose, ErrorCode, Event, EventKind, Force, ForceModelKind,
    InstrumentDescription, InstrumentState, JoinRequest, Joined, Leave, LocalModel, LocalPlane,
    ObserveMessage, Pose, Role, SceneDescription, SceneSummary, ServerMessage, StationError,
    StationMessage, SurfaceFrame, SurfaceMesh, Vec3, observe_message, server_message,
    station_message,
};
use prost::Message;
use prost_types::{FileDescriptorProto, FileDescriptorSet, SourceCodeInfo};

const PACKAGE: &str = "laparo.v1";

fn descriptor_set() -> FileDescriptorSet {
    FileDescriptorSet::decode(FILE_DESCRIPTOR_SET).expect("FILE_DESCRIPTOR_SET decodes")
}

fn contract_files(set: &FileDescriptorSet) -> Vec<&FileDescriptorProto> {
    set.file.iter().filter(|f| f.package() == PACKAGE).collect()
}

#[test]
fn descriptor_set_holds_the_package_and_every_import() {
    let set = descriptor_set();
    let names: BTreeSet<&str> = set.file.iter().map(|f| f.name()).collect();
    for file in [
        "laparo/v1/geometry.proto",
        "laparo/v1/force.proto",
        "laparo/v1/scene.proto",
        "laparo/v1/frame.proto",
        "laparo/v1/event.proto",
        "laparo/v1/session.proto",
        "laparo/v1/station.proto",
        "laparo/v1/observe.proto",
        "laparo/v1/recording.proto",
        "laparo/v1/services.proto",
    ] {
        assert!(names.contains(file), "{file} missing from {names:?}");
    }
    for file in contract_files(&set) {
        assert_eq!(file.syntax(), "proto3", "{}", file.name());
    }
    // Reflection serves the set as it is: it must be closed under imports.
    for file in &set.file {
        for dep in &file.dependency {
            assert!(
                names.contains(dep.as_str()),
                "{} imports {dep}, which is not in the set",
                file.name()
            );
        }
    }
    assert!(names.contains("google/protobuf/timestamp.proto"));
}

/// (service, method, input, output, client streaming, server streaming)
#[rustfmt::skip]
const METHODS: &[(&str, &str, &str, &str, bool, bool)] = &[
    ("Scenes", "ListScenes", "ListScenesRequest", "ListScenesResponse", false, false),
    ("Scenes", "GetScene", "GetSceneRequest", "SceneDescription", false, false),
    ("Sessions", "CreateSession", "CreateSessionRequest", "SessionInfo", false, false),
    ("Sessions", "GetSession", "GetSessionRequest", "SessionInfo", false, false),
    ("Sessions", "ListSessions", "ListSessionsRequest", "ListSessionsResponse", false, false),
    ("Sessions", "CloseSession", "CloseSessionRequest", "CloseSessionResponse", false, false),
    ("Sessions", "EvictStation", "EvictStationRequest", "EvictStationResponse", false, false),
    ("Station", "Join", "StationMessage", "ServerMessage", true, true),
    ("Station", "Attach", "JoinRequest", "AttachMessage", false, true),
    ("Station", "SendPoses", "SendPosesRequest", "SendPosesResponse", false, false),
    ("Observe", "Observe", "ObserveRequest", "ObserveMessage", false, true),
    ("Recordings", "ListRecordings", "ListRecordingsRequest", "ListRecordingsResponse", false, false),
    ("Recordings", "Replay", "ReplayRequest", "ObserveMessage", false, true),
];

#[test]
fn services_have_exactly_the_expected_methods_and_streaming() {
    let set = descriptor_set();
    let services: Vec<_> = contract_files(&set)
        .into_iter()
        .flat_map(|f| &f.service)
        .collect();

    let expected_services: BTreeSet<&str> = METHODS.iter().map(|m| m.0).collect();
    let actual_services: BTreeSet<&str> = services.iter().map(|s| s.name()).collect();
    assert_eq!(actual_services, expected_services);

    for service in &services {
        let actual: BTreeSet<&str> = service.method.iter().map(|m| m.name()).collect();
        let expected: BTreeSet<&str> = METHODS
            .iter()
            .filter(|m| m.0 == service.name())
            .map(|m| m.1)
            .collect();
        assert_eq!(actual, expected, "methods of {}", service.name());
    }

    for &(service, method, input, output, client_streaming, server_streaming) in METHODS {
        let m = services
            .iter()
            .find(|s| s.name() == service)
            .and_then(|s| s.method.iter().find(|m| m.name() == method))
            .unwrap_or_else(|| panic!("{service}.{method} missing"));
        assert_eq!(
            m.input_type(),
            format!(".{PACKAGE}.{input}"),
            "{service}.{method}"
        );
        assert_eq!(
            m.output_type(),
            format!(".{PACKAGE}.{output}"),
            "{service}.{method}"
        );
        assert_eq!(
            m.client_streaming(),
            client_streaming,
            "{service}.{method} client streaming"
        );
        assert_eq!(
            m.server_streaming(),
            server_streaming,
            "{service}.{method} server streaming"
        );
    }
}

#[test]
fn generated_services_use_the_described_names() {
    let generated = [
        v1::scenes_server::SERVICE_NAME,
        v1::sessions_server::SERVICE_NAME,
        v1::station_server::SERVICE_NAME,
        v1::observe_server::SERVICE_NAME,
        v1::recordings_server::SERVICE_NAME,
    ];
    let described: BTreeSet<String> = METHODS
        .iter()
        .map(|m| format!("{PACKAGE}.{}", m.0))
        .collect();
    assert_eq!(
        generated
            .iter()
            .map(|s| s.to_string())
            .collect::<BTreeSet<_>>(),
        described
    );
}

// Source-location path components, from descriptor.proto.
const FILE_SYNTAX: i32 = 12;
const FILE_MESSAGE: i32 = 4;
const FILE_ENUM: i32 = 5;
const FILE_SERVICE: i32 = 6;
const MESSAGE_FIELD: i32 = 2;
const MESSAGE_NESTED: i32 = 3;
const MESSAGE_ENUM: i32 = 4;
const MESSAGE_ONEOF: i32 = 8;
const ENUM_VALUE: i32 = 2;
const SERVICE_METHOD: i32 = 2;

fn leading_comment<'a>(info: &'a SourceCodeInfo, path: &[i32]) -> Option<&'a str> {
    info.location
        .iter()
        .find(|l| l.path == path)
        .and_then(|l| l.leading_comments.as_deref())
        .map(str::trim)
        .filter(|c| !c.is_empty())
}

fn undocumented_enum(
    info: &SourceCodeInfo,
    path: &[i32],
    e: &prost_types::EnumDescriptorProto,
    missing: &mut Vec<String>,
) {
    if leading_comment(info, path).is_none() {
        missing.push(format!("enum {}", e.name()));
    }
    for (i, v) in e.value.iter().enumerate() {
        let p = [path, &[ENUM_VALUE, i as i32]].concat();
        if leading_comment(info, &p).is_none() {
            missing.push(format!("enum value {}.{}", e.name(), v.name()));
        }
    }
}

fn undocumented_message(
    info: &SourceCodeInfo,
    path: &[i32],
    m: &prost_types::DescriptorProto,
    missing: &mut Vec<String>,
) {
    if leading_comment(info, path).is_none() {
        missing.push(format!("message {}", m.name()));
    }
    for (i, f) in m.field.iter().enumerate() {
        let p = [path, &[MESSAGE_FIELD, i as i32]].concat();
        if leading_comment(info, &p).is_none() {
            missing.push(format!("field {}.{}", m.name(), f.name()));
        }
    }
    for (i, o) in m.oneof_decl.iter().enumerate() {
        // proto3 `optional` fields live in synthetic oneofs that have no source.
        if m.field
            .iter()
            .any(|f| f.oneof_index == Some(i as i32) && f.proto3_optional())
        {
            continue;
        }
        let p = [path, &[MESSAGE_ONEOF, i as i32]].concat();
        if leading_comment(info, &p).is_none() {
            missing.push(format!("oneof {}.{}", m.name(), o.name()));
        }
    }
    for (i, n) in m.nested_type.iter().enumerate() {
        undocumented_message(
            info,
            &[path, &[MESSAGE_NESTED, i as i32]].concat(),
            n,
            missing,
        );
    }
    for (i, e) in m.enum_type.iter().enumerate() {
        undocumented_enum(
            info,
            &[path, &[MESSAGE_ENUM, i as i32]].concat(),
            e,
            missing,
        );
    }
}

/// Clients in other languages read the contract through reflection: every file,
/// message, field, oneof, enum, value, service and method carries a comment.
#[test]
fn every_element_of_the_contract_is_documented() {
    let set = descriptor_set();
    let mut missing = Vec::new();
    for file in contract_files(&set) {
        let info = file
            .source_code_info
            .as_ref()
            .unwrap_or_else(|| panic!("{} has no source info", file.name()));
        if leading_comment(info, &[FILE_SYNTAX]).is_none() {
            missing.push(format!("header of {}", file.name()));
        }
        for (i, m) in file.message_type.iter().enumerate() {
            undocumented_message(info, &[FILE_MESSAGE, i as i32], m, &mut missing);
        }
        for (i, e) in file.enum_type.iter().enumerate() {
            undocumented_enum(info, &[FILE_ENUM, i as i32], e, &mut missing);
        }
        for (i, s) in file.service.iter().enumerate() {
            if leading_comment(info, &[FILE_SERVICE, i as i32]).is_none() {
                missing.push(format!("service {}", s.name()));
            }
            for (j, m) in s.method.iter().enumerate() {
                let p = [FILE_SERVICE, i as i32, SERVICE_METHOD, j as i32];
                if leading_comment(info, &p).is_none() {
                    missing.push(format!("method {}.{}", s.name(), m.name()));
                }
            }
        }
    }
    assert!(missing.is_empty(), "undocumented: {missing:#?}");
}

fn screaming_snake(camel: &str) -> String {
    let mut out = String::new();
    for (i, c) in camel.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_uppercase());
    }
    out
}

#[test]
fn enums_open_with_unspecified_zero_and_prefix_their_values() {
    let set = descriptor_set();
    let enums: Vec<_> = contract_files(&set)
        .into_iter()
        .flat_map(|f| &f.enum_type)
        .collect();
    assert!(
        enums.len() >= 6,
        "expected the contract's enums, found {}",
        enums.len()
    );
    for e in enums {
        let prefix = format!("{}_", screaming_snake(e.name()));
        let first = &e.value[0];
        assert_eq!(first.number(), 0, "{}", e.name());
        assert_eq!(first.name(), format!("{prefix}UNSPECIFIED"), "{}", e.name());
        for v in &e.value {
            assert!(
                v.name().starts_with(&prefix),
                "{} in {}",
                v.name(),
                e.name()
            );
        }
    }
}

fn vec3(x: f64, y: f64, z: f64) -> Option<Vec3> {
    Some(Vec3 { x, y, z })
}

fn pose() -> Option<Pose> {
    Some(Pose {
        tip: vec3(0.01, -0.02, 0.05),
        axis: vec3(0.0, 0.6, 0.8),
    })
}

fn scene() -> SceneDescription {
    SceneDescription {
        summary: Some(SceneSummary {
            name: "liver".into(),
            description: "SOFA's liver, 0.2 m across".into(),
            vertex_count: 181,
            tetrahedron_count: 596,
            surface_vertex_count: 3,
            surface_triangle_count: 1,
            mechanics_rate_hz: 60.0,
            integrator: "semi_implicit_euler".into(),
            instruments: vec!["grasper".into()],
            force_model: ForceModelKind::Geometric.into(),
        }),
        rest_surface: Some(SurfaceMesh {
            positions: vec![0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.1, 0.0],
            triangles: vec![0, 1, 2],
        }),
        instruments: vec![InstrumentDescription {
            name: "grasper".into(),
            radius_m: 0.005,
            length_m: 0.3,
            trocar: vec3(0.0, 0.15, 0.25),
            tip_contact: true,
            shaft_contact: true,
        }],
        gravity: vec3(0.0, 0.0, -9.81),
    }
}

fn instrument_state() -> InstrumentState {
    InstrumentState {
        tick: 42,
        sim_time_s: 0.7,
        instrument: "grasper".into(),
        station_id: Some(3),
        pose: pose(),
        pose_sequence: Some(1234),
        contact: ContactState::TipAndShaft.into(),
        held_vertex_count: 5,
        held_surface_vertices: vec![7, 3, 120, 121, 9],
        local_model: Some(LocalModel {
            tick: 42,
            sim_time_s: 0.7,
            pose: pose(),
            tip_plane: Some(LocalPlane {
                active: true,
                normal: vec3(0.0, 0.0, 1.0),
                anchor: vec3(0.01, -0.02, 0.051),
                stiffness_n_per_m: 350.0,
                drag_n: vec3(0.05, 0.0, 0.0),
            }),
            shaft_plane: Some(LocalPlane {
                active: false,
                ..Default::default()
            }),
            force_model: ForceModelKind::Calibrated.into(),
            young_modulus_pa: Some(3.0e3),
        }),
        force: Some(Force {
            force: vec3(0.0, 0.0, 0.35),
            axial_n: 0.28,
            torque: vec3(-0.01, 0.0, 0.0),
            magnitude_n: 0.35,
        }),
    }
}

fn surface_frame() -> SurfaceFrame {
    SurfaceFrame {
        tick: 42,
        sim_time_s: 0.7,
        positions: vec![0.0, 0.0, 0.001, 0.1, 0.0, 0.0, 0.0, 0.1, 0.0],
    }
}

fn event() -> Event {
    Event {
        tick: 42,
        sim_time_s: 0.7,
        kind: EventKind::ContactBegan.into(),
        station_id: Some(3),
        instrument: Some("grasper".into()),
        detail: "tip touched the liver".into(),
    }
}

fn round_trip<M: Message + Default + PartialEq + std::fmt::Debug>(message: &M) {
    let bytes = message.encode_to_vec();
    let decoded = M::decode(bytes.as_slice()).expect("decodes");
    assert_eq!(&decoded, message);
}

#[test]
fn server_message_round_trips_every_variant() {
    use server_message::Kind;
    let variants = [
        Kind::Joined(Joined {
            station_id: 3,
            session_id: "s-1".into(),
            scene: Some(scene()),
            instruments: vec!["grasper".into()],
            surface_frame_rate_hz: 30.0,
            tick: 40,
            max_pose_rate_hz: 2000.0,
        }),
        Kind::SurfaceFrame(surface_frame()),
        Kind::InstrumentState(instrument_state()),
        Kind::Event(event()),
        Kind::Error(StationError {
            code: ErrorCode::InvalidPose.into(),
            message: "axis has length 0.5, not 1".into(),
            sequence: Some(1235),
            instrument: Some("grasper".into()),
        }),
    ];
    for kind in variants {
        round_trip(&ServerMessage { kind: Some(kind) });
    }
}

#[test]
fn station_and_observe_messages_round_trip_every_variant() {
    use observe_message::Kind as Out;
    use station_message::Kind as In;
    for kind in [
        In::Open(JoinRequest {
            session_id: "s-1".into(),
            role: Role::Trainee.into(),
            instruments: vec!["grasper".into()],
            surface_frame_rate_hz: Some(30.0),
            client_name: "station-2".into(),
        }),
        In::Pose(DevicePose {
            instrument: "grasper".into(),
            pose: pose(),
            device_time_s: 12.345,
            sequence: 1234,
        }),
        In::Leave(Leave {
            reason: "done".into(),
        }),
        In::Heartbeat(v1::Heartbeat {}),
    ] {
        round_trip(&StationMessage { kind: Some(kind) });
    }
    for kind in [
        Out::Scene(scene()),
        Out::SurfaceFrame(surface_frame()),
        Out::InstrumentState(instrument_state()),
        Out::Event(event()),
    ] {
        round_trip(&ObserveMessage { kind: Some(kind) });
    }
}

/// `optional` fields keep "absent" apart from zero: no contact means no Young's
/// modulus, not a modulus of 0 Pa.
#[test]
fn optional_fields_distinguish_absent_from_zero() {
    let mut model = instrument_state().local_model.unwrap();
    for value in [None, Some(0.0)] {
        model.young_modulus_pa = value;
        let decoded = LocalModel::decode(model.encode_to_vec().as_slice()).unwrap();
        assert_eq!(decoded.young_modulus_pa, value);
    }
}

/// Surface positions travel packed: 4 bytes a coordinate, not 5.
#[test]
fn surface_positions_are_packed_floats() {
    let vertices = 10_000;
    let frame = SurfaceFrame {
        tick: 1,
        sim_time_s: 0.0,
        positions: vec![0.5; 3 * vertices],
    };
    let payload = 3 * vertices * 4;
    let len = frame.encoded_len();
    assert!(
        len >= payload && len < payload + 32,
        "{len} bytes for {payload} bytes of floats"
    );
}
