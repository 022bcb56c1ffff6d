//! `/foxglove/scene`: read back from a recorded push with the schema the file
//! holds, each update draws its tick's recorded surface, shafts and forces.

use foxglove::Encode;
use foxglove::schemas::{ArrowPrimitive, CylinderPrimitive, Quaternion, SceneEntity, SceneUpdate};
use laparo_proto::force::wire::to_vec3;
use nalgebra::{UnitQuaternion, Vector3};

use super::super::foxglove_scene::{ARROW_M_PER_N, FRAME_ID, LIVER_ID, SceneUpdates, force_id};
use super::*;

/// The rotation a Foxglove quaternion stands for, checked to be of unit length.
fn rotation(q: &Quaternion) -> UnitQuaternion<f64> {
    let q = nalgebra::Quaternion::new(q.w, q.x, q.y, q.z);
    assert!(
        (q.norm() - 1.0).abs() < 1e-12,
        "not a unit quaternion: {q:?}"
    );
    UnitQuaternion::new_unchecked(q)
}

fn entity<'a>(update: &'a SceneUpdate, id: &str) -> &'a SceneEntity {
    let found: Vec<_> = update.entities.iter().filter(|e| e.id == id).collect();
    assert_eq!(found.len(), 1, "entities named {id}");
    found[0]
}

fn vec3(v: &v1::Vec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// Checks that `cylinder` is the shaft of `description` at pose `pose`: its
/// orientation turns +z onto the axis, its centre is half a length from the tip
/// along it, and it is as long and as wide as the instrument.
fn assert_shaft(
    cylinder: &CylinderPrimitive,
    pose: &v1::Pose,
    description: &v1::InstrumentDescription,
) {
    let tip = vec3(pose.tip.as_ref().unwrap());
    let axis = vec3(pose.axis.as_ref().unwrap());
    let p = cylinder.pose.unwrap();
    let z = rotation(&p.orientation.unwrap()) * Vector3::z();
    assert!((z - axis).norm() < 1e-6, "cylinder z {z:?}, axis {axis:?}");
    let c = p.position.unwrap();
    let centre = Vector3::new(c.x, c.y, c.z);
    let half = centre - tip;
    assert!(
        (half.norm() - description.length_m / 2.0).abs() < 1e-9,
        "centre {} m from the tip",
        half.norm()
    );
    assert!((half - axis * (description.length_m / 2.0)).norm() < 1e-9);
    let size = cylinder.size.unwrap();
    assert_eq!(size.z, description.length_m);
    assert_eq!(
        (size.x, size.y),
        (2.0 * description.radius_m, 2.0 * description.radius_m)
    );
}

/// Checks that `arrow` draws `force` (N): its length is [`ARROW_M_PER_N`] per
/// newton and it points along the force.
fn assert_force(arrow: &ArrowPrimitive, force: &Vector3<f64>) {
    let length = arrow.shaft_length + arrow.head_length;
    assert!(
        (length - ARROW_M_PER_N * force.norm()).abs() <= 1e-12 * length.max(1.0),
        "arrow of {length} m for {} N",
        force.norm()
    );
    assert!(arrow.shaft_length > 0.0 && arrow.head_length > 0.0);
    let x = rotation(&arrow.pose.unwrap().orientation.unwrap()) * Vector3::x();
    assert!(
        (x - force.normalize()).norm() < 1e-6,
        "arrow along {x:?}, force {force:?}"
    );
}

#[test]
fn every_recorded_tick_is_drawn_for_foxglove() {
    let dir = temp();
    let path = dir.path().join("run.mcap");
    let (frames, _, header) = record_script(&path, 40);
    let rec = Recording::open(&path).unwrap();

    // The channel's schema is the one the foxglove crate states, byte for byte, so
    // decoding with the crate's type is decoding with the file's schema.
    let summary = rec.mcap_summary();
    let channel = summary
        .channels
        .values()
        .find(|c| c.topic == TOPIC_FOXGLOVE_SCENE)
        .expect("a /foxglove/scene channel");
    let stated = SceneUpdate::get_schema().unwrap();
    let schema = channel.schema.as_ref().unwrap();
    assert_eq!(channel.message_encoding, "protobuf");
    assert_eq!(
        (schema.name.as_str(), schema.encoding.as_str()),
        (SCHEMA_FOXGLOVE_SCENE, "protobuf")
    );
    assert_eq!(stated.name, SCHEMA_FOXGLOVE_SCENE);
    assert_eq!(&schema.data[..], &stated.data[..]);
    let set = prost_types::FileDescriptorSet::decode(&*schema.data).unwrap();
    assert!(
        set.file.iter().any(|f| f.package() == "foxglove"
            && f.message_type.iter().any(|m| m.name() == "SceneUpdate"))
    );

    let updates = rec.scene_updates().unwrap();
    let surfaces = rec.surfaces().unwrap();
    // Every third tick at 60 Hz (at most 20 a second), from the first.
    let stride = super::foxglove_scene::stride(60.0);
    let surfaces: Vec<_> = surfaces
        .into_iter()
        .filter(|s| super::foxglove_scene::drawn(s.message.tick, stride))
        .collect();
    let frames: Vec<_> = frames
        .into_iter()
        .filter(|f| super::foxglove_scene::drawn(f.tick, stride))
        .collect();
    assert_eq!(updates.len(), frames.len());
    assert_eq!(updates.len(), 40usize.div_ceil(stride as usize));
    let scene = &header.description;
    let triangles = &scene.rest_surface.as_ref().unwrap().triangles;
    assert!(!triangles.is_empty() && triangles.len() % 3 == 0);
    let left = &scene.instruments[0];
    let (mut pushed, mut by_tip) = (0, 0);
    for ((update, surface), frame) in updates.iter().zip(&surfaces).zip(&frames) {
        assert_eq!(update.log_time, surface.log_time);
        let update = &update.message;
        assert_eq!(update.entities.len(), 1 + 2 * scene.instruments.len());
        for e in &update.entities {
            assert_eq!(e.frame_id, FRAME_ID);
            let t = e.timestamp.unwrap();
            assert_eq!(
                u64::from(t.sec()) * 1_000_000_000 + u64::from(t.nsec()),
                surface.log_time
            );
        }

        // The liver: the recorded surface of the same tick, triangle by triangle.
        let liver = entity(update, LIVER_ID);
        assert_eq!(liver.triangles.len(), 1);
        let list = &liver.triangles[0];
        let corners: Vec<[f32; 3]> = list
            .indices
            .iter()
            .map(|&i| {
                let p = list.points[i as usize];
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect();
        assert_eq!(corners.len(), triangles.len(), "3 corners per triangle");
        let positions = &surface.message.positions;
        for (corner, &v) in corners.iter().zip(triangles) {
            let v = 3 * v as usize;
            let recorded = [positions[v], positions[v + 1], positions[v + 2]];
            assert_eq!(corner.map(f32::to_bits), recorded.map(f32::to_bits));
        }

        // The left instrument: its shaft, and its force once it pushes.
        let state = &frame.instruments[0];
        let shaft = entity(update, &left.name);
        assert_eq!(shaft.cylinders.len(), 1);
        assert_shaft(&shaft.cylinders[0], state.pose.as_ref().unwrap(), left);
        let force = vec3(state.force.as_ref().unwrap().force.as_ref().unwrap());
        let arrows = &entity(update, &force_id(&left.name)).arrows;
        if force.norm() > 0.0 {
            pushed += 1;
            assert_eq!(arrows.len(), 1);
            assert_force(&arrows[0], &force);
            // From a point of the shaft: the tip when the tip alone pushes.
            let from = arrows[0].pose.unwrap().position.unwrap();
            let from = Vector3::new(from.x, from.y, from.z);
            let pose = state.pose.as_ref().unwrap();
            let (tip, axis) = (
                vec3(pose.tip.as_ref().unwrap()),
                vec3(pose.axis.as_ref().unwrap()),
            );
            let along = (from - tip).dot(&axis);
            assert!(
                (from - tip - axis * along).norm() < 1e-9,
                "{from:?} is off the axis"
            );
            assert!((-1e-12..=left.length_m).contains(&along));
            if state.contact == v1::ContactState::Tip as i32 {
                assert!((from - tip).norm() < 1e-12);
                by_tip += 1;
            }
        } else {
            assert!(arrows.is_empty(), "an arrow without force");
        }

        // The right instrument never had a pose: nothing drawn for it.
        let right = &scene.instruments[1].name;
        assert!(frame.instruments[1].pose.is_none());
        assert!(entity(update, right).cylinders.is_empty());
        assert!(entity(update, &force_id(right)).arrows.is_empty());
    }
    assert!(
        pushed > 5 && pushed < frames.len(),
        "{pushed} ticks with force"
    );
    assert!(by_tip > 0, "the tip never pushed alone");
}

#[test]
fn a_shaft_is_drawn_along_any_axis_and_a_shaft_force_from_where_it_applies() {
    let mut script = Script::new();
    let frame = script.tick(0);
    let scene = script.header(SystemTime::now()).description;
    let updates = SceneUpdates::new(&scene);
    let left = &scene.instruments[0];
    let s = 0.5_f64.sqrt();
    // Along the axes both ways (−z is the half turn), and slanted.
    for axis in [
        Vector3::z(),
        -Vector3::z(),
        Vector3::x(),
        -Vector3::x(),
        Vector3::y(),
        -Vector3::y(),
        Vector3::new(s, 0.0, -s),
        Vector3::new(0.3, -0.4, 0.5).normalize(),
        Vector3::new(1e-9, 0.0, -1.0).normalize(),
    ] {
        let tip = nalgebra::Point3::new(0.01, -0.02, 0.03);
        let pose = to_pose(&tip, &Unit::new_normalize(axis));
        // A shaft contact: the force applies at Q, 4 cm up the axis, not at the tip.
        let q = tip + axis * 0.04;
        let normal = Unit::new_normalize(axis.cross(&Vector3::new(0.2, 0.7, 0.1)));
        let model = laparo_proto::force::LocalModel {
            shaft_plane: Some(laparo_proto::force::Plane {
                normal,
                anchor: q + normal.into_inner() * 0.003,
                stiffness: 400.0,
                drag: Vector3::zeros(),
            }),
            ..laparo_proto::force::LocalModel::free(1, 0.1, tip, Unit::new_normalize(axis))
        };
        let applied = model.force(&tip, &Unit::new_normalize(axis));
        assert!((applied.point - q).norm() < 1e-12);
        let mut frame = Frame {
            surface: frame.surface.clone(),
            instruments: frame.instruments.clone(),
            ..frame
        };
        frame.instruments[0].pose = Some(pose);
        frame.instruments[0].local_model = Some(v1::LocalModel::from(&model));
        frame.instruments[0].force = Some(v1::Force {
            force: Some(to_vec3(&applied.force)),
            ..Default::default()
        });
        let update = updates.update(&frame, 1);
        let shaft = entity(&update, &left.name);
        assert_shaft(&shaft.cylinders[0], &pose, left);
        let arrows = &entity(&update, &force_id(&left.name)).arrows;
        assert_eq!(arrows.len(), 1);
        assert_force(&arrows[0], &applied.force);
        let from = arrows[0].pose.unwrap().position.unwrap();
        assert!((Vector3::new(from.x, from.y, from.z) - q.coords).norm() < 1e-12);
    }
}

#[test]
fn scene_updates_are_drawn_at_most_twenty_a_second_with_the_smallest_stride() {
    use super::super::foxglove_scene::{MAX_RATE_HZ, drawn, stride};
    for rate in [1.0, 15.0, 20.0, 20.5, 30.0, 60.0, 120.0, 1000.0, 1001.0] {
        let k = stride(rate);
        assert!(rate / k as f64 <= MAX_RATE_HZ, "{rate} Hz: stride {k}");
        assert!(
            k == 1 || rate / (k - 1) as f64 > MAX_RATE_HZ,
            "{rate} Hz: stride {k}"
        );
        // Over a simulated second of ticks: the first tick, then every k-th.
        let ticks = rate.round() as u64;
        let n = (1..=ticks).filter(|&t| drawn(t, k)).count() as u64;
        assert_eq!(n, ticks.div_ceil(k), "{rate} Hz");
        assert!(drawn(1, k));
    }
    assert_eq!(stride(f64::NAN), 1);
    assert_eq!(stride(0.0), 1);
}
