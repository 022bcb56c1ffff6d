//! How much a server takes on at once: sessions, connections and concurrent
//! replays, with defaults derived from the machine, and the `RESOURCE_EXHAUSTED`
//! answer past each limit (naming the limit and the flag that sets it).
//!
//! The defaults, for a machine of `c` cores (`available_parallelism`), `m` bytes of
//! memory (`MemTotal`) and a soft limit of `f` file descriptors (`RLIMIT_NOFILE`):
//!
//! - **sessions** = max(1, min(16·c, m / 64 MiB)). A session of a scene larger
//!   than about 22,000 tetrahedra counts as several ([`session_weight`]: its peak
//!   memory over 64 MiB, at 2.6 kB a tetrahedron), so that the limit bounds memory
//!   whatever scenes are offered. A default session ticks at
//!   60 Hz; its tick, its recorder and the encoding of its frames for two 1 kHz
//!   stations and an observer or two take a few percent of a core. The soak bench's
//!   ramp (`cargo bench -p laparo-tests --bench soak -- --ramp`) on a 2-core machine,
//!   with its clients on the same cores, held 32 sessions without a missed deadline
//!   and missed at 40: 16 a core. A default session holds about 3.3 MiB (RSS) and
//!   two threads (mechanics, recorder); 64 MiB each leaves room for sessions of
//!   larger meshes on a small machine.
//! - **connections** = max(16, min(8·sessions + 64, f − 128 − 2·sessions)). A
//!   session has two stations and a few observers; 64 more for listing, replays
//!   and tools. Each connection is a descriptor, each session holds up to two
//!   (its recording, a mesh while it loads) and 128 are kept for the process's
//!   other files, so that the limit refuses connections before `accept` runs out
//!   of descriptors.
//! - **connections per peer** = max(8, connections / 4), counted by address (an
//!   IPv6 /64 as one address), loopback not counted
//!   ([`connections_per_peer_for`]): one address cannot take every slot (a peer
//!   that opens connections and trickles nothing on them refused every other
//!   client), yet a quarter leaves room for a classroom behind one NAT address.
//! - **replays** = max(1, min(32·c, m / 4 / 16 MiB)). A replay holds one
//!   decompressed chunk (at most a few MiB) and a read-ahead of messages; its
//!   reading runs in short bursts on the blocking pool, so what bounds it is memory
//!   and the cores that decode: a quarter of the memory at 16 MiB each. A replay
//!   that re-simulates builds its scene and counts as its memory over 16 MiB
//!   ([`replay_weight`]).

use std::sync::Arc;

use laparo_proto::v1;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tonic::Status;

/// Budget of memory per session in the default limit, bytes.
const SESSION_MEMORY: u64 = 64 << 20;
/// Budget of memory per replay in the default limit, bytes.
const REPLAY_MEMORY: u64 = 16 << 20;
/// Sessions per core in the default limit.
const SESSIONS_PER_CORE: usize = 16;
/// Replays per core in the default limit.
const REPLAYS_PER_CORE: usize = 32;
/// File descriptors kept for the process's own files.
const RESERVED_FDS: u64 = 128;

/// What the machine offers, as the defaults need it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Machine {
    pub cores: usize,
    pub memory_bytes: u64,
    /// Soft `RLIMIT_NOFILE`.
    pub fd_limit: u64,
}

impl Machine {
    /// This machine (1 core, 1 GiB and 1024 descriptors where it cannot tell).
    pub fn this() -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        // SAFETY: sysconf reads a system constant.
        let (pages, page) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        let memory_bytes = if pages > 0 && page > 0 {
            pages as u64 * page as u64
        } else {
            1 << 30
        };
        let mut limit = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes into the struct given.
        let fd_limit = if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut limit) } == 0 {
            limit.rlim_cur
        } else {
            1024
        };
        Machine {
            cores,
            memory_bytes,
            fd_limit,
        }
    }
}

/// The connection default for `sessions` sessions and `fd_limit` descriptors.
fn connections_for(sessions: usize, fd_limit: u64) -> usize {
    let fds_left = fd_limit.saturating_sub(RESERVED_FDS.saturating_add(2 * sessions as u64));
    sessions
        .saturating_mul(8)
        .saturating_add(64)
        .min(usize::try_from(fds_left).unwrap_or(usize::MAX))
        .max(16)
}

/// Fewest connections one peer address may hold in the default per-peer limit: a
/// browser opens up to six HTTP/1.1 connections to one origin (the console's
/// gRPC-web calls and streams each hold one), and the command-line client one
/// each run, so eight let a trainee's browser and a tool or two share an address
/// even on the smallest server (16 connections).
pub const MIN_CONNECTIONS_PER_PEER: usize = 8;

/// The default per-peer connection limit for a server of `connections`
/// connections: a quarter of them, at least [`MIN_CONNECTIONS_PER_PEER`]. At
/// most four addresses can fill the server (a peer that holds connections without
/// using them leaves three quarters to everyone else), while a lab of trainees
/// behind one NAT address still gets a quarter of the server (80 connections of
/// the 320 of a 2-core default). Loopback peers are not counted per address
/// ([`connections`](super::connections)): a proxy on the same host brings every
/// client from loopback, and any local process may pick any address of
/// 127.0.0.0/8, so there the limit would refuse honest clients and not bind
/// anyone else; the global limit still does.
pub fn connections_per_peer_for(connections: usize) -> usize {
    (connections / 4).max(MIN_CONNECTIONS_PER_PEER)
}

/// Limits on what a server takes on at once (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacity {
    /// Open sessions (`--max-sessions`).
    pub sessions: usize,
    /// Open connections (`--max-connections`).
    pub connections: usize,
    /// Open connections of one peer address (`--max-connections-per-peer`);
    /// loopback peers are not counted.
    pub connections_per_peer: usize,
    /// Replays streaming at once (`--max-replays`).
    pub replays: usize,
}

impl Capacity {
    /// The defaults for `machine` (formulas in the module documentation).
    pub fn for_machine(machine: Machine) -> Self {
        let cores = machine.cores.max(1);
        let sessions = (SESSIONS_PER_CORE * cores)
            .min(usize::try_from(machine.memory_bytes / SESSION_MEMORY).unwrap_or(usize::MAX))
            .max(1);
        let connections = connections_for(sessions, machine.fd_limit);
        let replays = (REPLAYS_PER_CORE * cores)
            .min(usize::try_from(machine.memory_bytes / 4 / REPLAY_MEMORY).unwrap_or(usize::MAX))
            .max(1);
        Capacity {
            sessions,
            connections,
            connections_per_peer: connections_per_peer_for(connections),
            replays,
        }
    }

    /// These defaults with `sessions` sessions, and the connection defaults that
    /// follow from it.
    pub fn with_sessions(self, sessions: usize, machine: Machine) -> Self {
        let connections = connections_for(sessions, machine.fd_limit);
        Capacity {
            sessions,
            connections,
            connections_per_peer: connections_per_peer_for(connections),
            replays: self.replays,
        }
    }

    /// These limits with `connections` connections, and the per-peer default
    /// that follows from it.
    pub fn with_connections(self, connections: usize) -> Self {
        Capacity {
            connections,
            connections_per_peer: connections_per_peer_for(connections),
            ..self
        }
    }

    /// The defaults for this machine.
    pub fn of_this_machine() -> Self {
        Self::for_machine(Machine::this())
    }
}

impl Default for Capacity {
    fn default() -> Self {
        Self::of_this_machine()
    }
}

/// Memory a session holds beyond its mesh, bytes (the default scene's session peaks
/// at 8 MB resident in `laparo-server run`).
const SESSION_BASE_MEMORY: u64 = 8 << 20;
/// Memory a session holds per tetrahedron at its peak, while the scene is built,
/// bytes: SOFA's liver refined three times (305,152 tetrahedra, corotational,
/// implicit) peaks at 790 MB resident in `laparo-server run`, about 2.6 kB each.
const SESSION_MEMORY_PER_TET: u64 = 2600;

/// How many sessions of the [`SESSION_MEMORY`] the session limit is sized by a
/// session of `tets` tetrahedra counts as: one for every scene up to 22,584
/// tetrahedra (liver-20k), several for larger ones (80,000 tetrahedra 4; 300,000,
/// or SOFA's liver refined three times, 12), so that sessions of large scenes
/// cannot take more memory than the limit was sized for.
pub fn session_weight(tets: usize) -> usize {
    scene_memory_in(tets, SESSION_MEMORY)
}

/// The tetrahedra of a scene as described (0 for a description without its
/// summary): what [`session_weight`] and [`replay_weight`] take.
pub fn tetrahedra(description: &v1::SceneDescription) -> usize {
    description
        .summary
        .as_ref()
        .map_or(0, |s| s.tetrahedron_count as usize)
}

/// How many replays of the [`REPLAY_MEMORY`] the replay limit is sized by a replay
/// that re-simulates a scene of `tets` tetrahedra counts as: it builds the scene,
/// and holds what a session of it would ([`session_weight`]'s memory). A replay as
/// recorded counts as one whatever its scene.
pub fn replay_weight(tets: usize) -> usize {
    scene_memory_in(tets, REPLAY_MEMORY)
}

/// The peak memory of a built scene of `tets` tetrahedra in units of `unit` bytes,
/// rounded up, at least one.
fn scene_memory_in(tets: usize, unit: u64) -> usize {
    let bytes =
        SESSION_BASE_MEMORY.saturating_add(SESSION_MEMORY_PER_TET.saturating_mul(tets as u64));
    usize::try_from(bytes.div_ceil(unit))
        .unwrap_or(usize::MAX)
        .max(1)
}

/// `RESOURCE_EXHAUSTED` for a session of scene `scene` (`tets` tetrahedra, counting
/// as `weight` sessions) when sessions counting as `open` of `limit` run.
pub fn too_large_a_session(
    scene: &str,
    tets: usize,
    weight: usize,
    open: usize,
    limit: usize,
) -> Status {
    Status::resource_exhausted(format!(
        "scene `{scene}` has {tets} tetrahedra and counts as {weight} of the {limit} sessions \
         the server runs at once (--max-sessions: one session per {} MiB); sessions counting \
         as {open} are open: close some (CloseSession) or start the server with a higher \
         --max-sessions",
        SESSION_MEMORY >> 20
    ))
}

/// `RESOURCE_EXHAUSTED` for a new session when `open` of `limit` are open.
pub fn too_many_sessions(limit: usize) -> Status {
    Status::resource_exhausted(format!(
        "the server runs {limit} sessions, its limit (--max-sessions): close one \
         (CloseSession) or start the server with a higher --max-sessions"
    ))
}

/// The replays a server streams at once: a permit each, held by the replay's
/// task until its stream ends.
#[derive(Clone, Debug)]
pub struct ReplaySlots {
    slots: Arc<Semaphore>,
    limit: usize,
}

impl ReplaySlots {
    pub fn new(limit: usize) -> Self {
        ReplaySlots {
            slots: Arc::new(Semaphore::new(limit)),
            limit,
        }
    }

    /// A slot, or `RESOURCE_EXHAUSTED` naming the limit and its flag.
    pub fn take(&self) -> Result<OwnedSemaphorePermit, Status> {
        self.slots.clone().try_acquire_owned().map_err(|_| {
            Status::resource_exhausted(format!(
                "the server streams {} replays at once, its limit (--max-replays): \
                 try again when one ends, or start the server with a higher --max-replays",
                self.limit
            ))
        })
    }

    /// `more` slots added to `held` (a re-simulated replay of a large scene counts
    /// as several replays, [`replay_weight`]), or `RESOURCE_EXHAUSTED` naming the
    /// scene's size, the limit and its flag.
    pub fn take_more(
        &self,
        held: &mut OwnedSemaphorePermit,
        more: usize,
        tets: usize,
    ) -> Result<(), Status> {
        if more == 0 {
            return Ok(());
        }
        let permits = u32::try_from(more).unwrap_or(u32::MAX);
        let extra = self
            .slots
            .clone()
            .try_acquire_many_owned(permits)
            .map_err(|_| {
                Status::resource_exhausted(format!(
                    "re-simulating this recording builds its scene of {tets} tetrahedra, \
                     which counts as {} of the {} replays the server streams at once \
                     (--max-replays: one replay per {} MiB), more than are free: try again \
                     when replays end, replay it as recorded, or start the server with a \
                     higher --max-replays",
                    more + 1,
                    self.limit,
                    REPLAY_MEMORY >> 20
                ))
            })?;
        held.merge(extra);
        Ok(())
    }

    /// Replays streaming now.
    pub fn in_use(&self) -> usize {
        self.limit - self.slots.available_permits()
    }
}

impl Default for ReplaySlots {
    fn default() -> Self {
        Self::new(Capacity::default().replays)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GIB: u64 = 1 << 30;

    #[test]
    fn a_two_core_machine_holds_32_sessions_as_measured() {
        let c = Capacity::for_machine(Machine {
            cores: 2,
            memory_bytes: 16 * GIB,
            fd_limit: 1 << 20,
        });
        assert_eq!(c.sessions, 32);
        assert_eq!(c.connections, 8 * 32 + 64);
        assert_eq!(c.connections_per_peer, 80);
        assert_eq!(c.replays, 64);
    }

    #[test]
    fn one_peer_gets_a_quarter_of_the_connections_and_never_fewer_than_a_browser_needs() {
        assert_eq!(connections_per_peer_for(320), 80);
        assert_eq!(connections_per_peer_for(16), MIN_CONNECTIONS_PER_PEER);
        assert_eq!(connections_per_peer_for(1), MIN_CONNECTIONS_PER_PEER);
        let machine = Machine {
            cores: 2,
            memory_bytes: 16 * GIB,
            fd_limit: 1 << 20,
        };
        let c = Capacity::for_machine(machine).with_sessions(4, machine);
        assert_eq!(c.connections, 8 * 4 + 64);
        assert_eq!(c.connections_per_peer, 24);
        let c = c.with_connections(1000);
        assert_eq!(c.connections_per_peer, 250);
    }

    #[test]
    fn memory_bounds_sessions_and_replays_on_a_small_machine() {
        let c = Capacity::for_machine(Machine {
            cores: 8,
            memory_bytes: GIB,
            fd_limit: 1 << 20,
        });
        assert_eq!(c.sessions, 16, "1 GiB at 64 MiB a session");
        assert_eq!(c.replays, 16, "a quarter of 1 GiB at 16 MiB a replay");
        let c = Capacity::for_machine(Machine {
            cores: 8,
            memory_bytes: 512 << 20,
            fd_limit: 1 << 20,
        });
        assert_eq!(c.sessions, 8);
        assert_eq!(c.replays, 8);
    }

    #[test]
    fn connections_stay_under_the_descriptor_limit() {
        let c = Capacity::for_machine(Machine {
            cores: 2,
            memory_bytes: 16 * GIB,
            fd_limit: 1024,
        });
        assert_eq!(c.connections, 8 * 32 + 64);
        let c = Capacity::for_machine(Machine {
            cores: 2,
            memory_bytes: 16 * GIB,
            fd_limit: 256,
        });
        assert_eq!(c.connections, 256 - 128 - 2 * 32);
        // Even a tiny limit leaves a few connections, and never zero sessions.
        let tiny = Capacity::for_machine(Machine {
            cores: 0,
            memory_bytes: 0,
            fd_limit: 0,
        });
        assert_eq!(tiny.sessions, 1);
        assert_eq!(tiny.replays, 1);
        assert_eq!(tiny.connections, 16);
    }

    #[test]
    fn a_replay_past_the_limit_is_refused_naming_the_flag_until_one_ends() {
        let slots = ReplaySlots::new(2);
        let a = slots.take().unwrap();
        let _b = slots.take().unwrap();
        let e = slots.take().unwrap_err();
        assert_eq!(e.code(), tonic::Code::ResourceExhausted);
        assert!(e.message().contains("--max-replays"), "{}", e.message());
        assert!(e.message().contains(" 2 "), "{}", e.message());
        assert_eq!(slots.in_use(), 2);
        drop(a);
        assert!(slots.take().is_ok());
    }

    #[test]
    fn the_session_refusal_names_the_limit_and_its_flag() {
        let e = too_many_sessions(64);
        assert_eq!(e.code(), tonic::Code::ResourceExhausted);
        assert!(e.message().contains("64 sessions"));
        assert!(e.message().contains("--max-sessions"));
    }

    #[test]
    fn a_session_counts_as_its_peak_memory_in_sessions_of_64_mib() {
        // The default scene and liver-20k are one session each; a session's count
        // is its base and per-tetrahedron memory over 64 MiB, rounded up.
        assert_eq!(session_weight(0), 1);
        assert_eq!(session_weight(596), 1);
        assert_eq!(session_weight(20_039), 1);
        assert_eq!(session_weight(22_584), 1);
        assert_eq!(session_weight(22_585), 2);
        assert_eq!(session_weight(596 * 64), 2);
        assert_eq!(session_weight(596 * 512), 12);
        // No overflow: an absurd size counts as more sessions than any limit.
        assert!(session_weight(usize::MAX) > 1 << 30);
        // A re-simulated replay counts in 16 MiB replays; the default scene as one.
        assert_eq!(replay_weight(596), 1);
        assert_eq!(replay_weight(596 * 64), 7);
        assert_eq!(replay_weight(596 * 512), 48);
        let e = too_large_a_session("big", 305_152, 12, 3, 8);
        assert_eq!(e.code(), tonic::Code::ResourceExhausted);
        for words in [
            "`big`",
            "305152 tetrahedra",
            "12 of the 8",
            "--max-sessions",
            "64 MiB",
        ] {
            assert!(e.message().contains(words), "{}", e.message());
        }
    }
}
