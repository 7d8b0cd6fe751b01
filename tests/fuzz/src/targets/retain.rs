//! A retained-memory directory at start: two generation files, read and chosen by the daemon's
//! own start-up code (`services::retain::startup`) and restored into an engine. Either what was
//! written is restored exactly, or a file is refused; never anything else.
//!
//! The first byte picks how the files are made:
//! - even: **written, then damaged.** The rest of the input gives the device words and the
//!   bytes of every `RETAIN` variable of the target's project, encoded by the daemon's encoder
//!   as generation `seq` in one slot and, optionally, an older generation in the other; then
//!   the newer file is optionally damaged (a burst of up to 4 bytes changed, cut short, or
//!   extended). The newer generation must be restored exactly when intact; when damaged, the
//!   older one exactly, or nothing if there is none.
//! - odd: **raw.** The rest is a file, with a correct CRC-32C appended so that the fuzzer gets
//!   past the checksum into the structure. What is accepted must encode back to the same bytes
//!   (a version 4 file), and whatever is restored must fit the engine.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plcd::config::{self, Restart};
use plcd::device::RetainSet;
use plcd::engine::Engine;
use plcd::project::{self, Project};
use plcd::services::retain::format::{self, Slot};
use plcd::services::retain::{startup, Store};

use crate::Bytes;

const CONFIG: &str = r#"
[retain]
ranges = ["D00000-D00009", "T0000-T0003", "C0000-C0003"]
[[program]]
name = "main"
file = "main.st"
"#;

/// Leaves, and arrays as whole records (version 4): of scalars, of two dimensions, of blocks
/// only one member of which is retained (its bytes packed), of arrays.
const MAIN: &str = "FUNCTION_BLOCK Keeper\nVAR RETAIN kept : INT; END_VAR\nVAR lost : INT; END_VAR\n\
                    lost := lost + 1;\nEND_FUNCTION_BLOCK\n\
                    PROGRAM main\nVAR RETAIN\n    count : DINT;\n    name : STRING[8];\n\
                    level : LREAL;\n    on : BOOL;\n    buf : ARRAY[1..3] OF INT;\n\
                    grid : ARRAY[0..1, -1..0] OF SINT;\n    rows : ARRAY[1..2] OF ARRAY[1..2] OF INT;\n\
                    END_VAR\nVAR keepers : ARRAY[1..2] OF Keeper; END_VAR\n\
                    count := count + 1;\nEND_PROGRAM\n";

const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

struct Fixture {
    project: Project,
    set: RetainSet,
    store: Store,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let config = config::parse(CONFIG, Path::new("plcd.toml")).expect("config");
        let set = RetainSet::new(&config.retain.ranges);
        let project = project::from_config(config, |_| Ok(MAIN.to_string())).expect("project");
        // Memory-backed where there is one: the target writes two files per input.
        let base = Path::new("/dev/shm");
        let base = if base.is_dir() { base.to_path_buf() } else { std::env::temp_dir() };
        let dir: PathBuf = base.join(format!("plcd-fuzz-retain-{}", std::process::id()));
        let store = Store::open(&dir).expect("a scratch directory");
        Fixture { project, set, store }
    })
}

/// What a generation holds, as the engine will see it.
#[derive(Debug, Clone, PartialEq)]
struct Held {
    words: Vec<u16>,
    variables: Vec<(String, Vec<u8>)>,
}

pub fn run(data: &[u8]) {
    let f = fixture();
    let mut input = Bytes::new(data);
    for slot in 0..2 {
        let _ = std::fs::remove_file(f.store.slot_path(slot));
    }
    if input.u8() & 1 == 0 {
        written_then_damaged(f, &mut input);
    } else {
        raw(f, input.rest());
    }
}

fn written_then_damaged(f: &Fixture, input: &mut Bytes<'_>) {
    let engine = Engine::new(&f.project, &[] as &[project::Watched]);
    let leaves = engine.retained_variables().records().to_vec();
    let held = |input: &mut Bytes<'_>| Held {
        words: (0..f.set.word_count()).map(|_| input.u16()).collect(),
        variables: leaves
            .iter()
            .map(|l| {
                let mut bytes = input.take(l.len as usize).to_vec();
                bytes.resize(l.len as usize, 0);
                (l.name.clone(), bytes)
            })
            .collect(),
    };
    let seq = u64::from(input.u16()) + 2;
    let newer_slot = usize::from(input.bool());
    let with_older = input.bool();
    let damage = input.u8() % 4;
    let (at, burst) = (usize::from(input.u16()), input.take(4).to_vec());
    let newer = held(input);
    let older = held(input);
    let encode = |seq: u64, h: &Held| {
        let types: Vec<&str> = leaves.iter().map(|l| l.ty.as_str()).collect();
        let mut section = Vec::new();
        let vars = h.variables.iter().zip(&types).map(|((n, b), t)| (n.as_str(), *t, &b[..]));
        format::encode_variables(vars, &mut section);
        let mut out = Vec::new();
        // The payload holds the masked words, as the writer's capture does.
        let mut memory = vec![0u16; 1 << 16];
        f.set.restore(&h.words, &mut memory);
        let mut words = Vec::new();
        f.set.capture(&memory, &mut words);
        format::encode(seq, 1_700_000_000_000, &f.set.words, &words, &section, &mut out);
        (out, Held { words, variables: h.variables.clone() })
    };
    let (mut newer_bytes, newer) = encode(seq, &newer);
    let (older_bytes, older) = encode(seq - 1, &older);
    let damaged = match damage {
        1 => {
            let at = at % newer_bytes.len();
            let mut changed = false;
            for (byte, b) in newer_bytes[at..].iter_mut().zip(&burst) {
                *byte ^= b;
                changed |= *b != 0;
            }
            changed
        }
        2 => {
            newer_bytes.truncate(at % newer_bytes.len());
            true
        }
        3 => {
            newer_bytes.extend_from_slice(&burst);
            !burst.is_empty()
        }
        _ => false,
    };
    std::fs::write(f.store.slot_path(newer_slot), &newer_bytes).expect("write");
    if with_older {
        std::fs::write(f.store.slot_path(1 - newer_slot), &older_bytes).expect("write");
    }
    let restored = restore(f);
    let expected = match (damaged, with_older) {
        (false, _) => Some(newer),
        (true, true) => Some(older),
        (true, false) => None,
    };
    assert_eq!(restored, expected, "damage {damage} at {at}: restored something else");
}

fn raw(f: &Fixture, body: &[u8]) {
    let mut bytes = body.to_vec();
    bytes.extend_from_slice(&CRC.checksum(body).to_le_bytes());
    if let Ok(generation) = format::decode(&bytes) {
        if generation.version == format::VERSION {
            let mut section = Vec::new();
            format::encode_saved(&generation.variables, &mut section);
            let mut again = Vec::new();
            let g = &generation;
            format::encode(g.seq, g.written_unix_ms, &g.ranges, &g.words, &section, &mut again);
            // The device layout word is this build's in `encode`: compare the rest.
            assert_eq!(again.len(), bytes.len(), "accepted, but encodes to another length");
            if g.device_words == u32::from_le_bytes(bytes[32..36].try_into().unwrap()) {
                assert!(
                    again[..32] == bytes[..32]
                        && again[36..again.len() - 4] == bytes[36..bytes.len() - 4],
                    "accepted, but encodes to other bytes"
                );
            }
        }
    }
    std::fs::write(f.store.slot_path(0), &bytes).expect("write");
    let _ = restore(f);
    assert!(matches!(f.store.read(1), Ok(Slot::Missing)), "the empty slot was touched");
}

/// Starts as the daemon does: reads the directory, restores into a new engine; what the engine
/// then holds, or `None` if nothing was restored.
fn restore(f: &Fixture) -> Option<Held> {
    let startup = startup(&f.store, &f.set, Restart::Warm);
    let words = startup.words.as_ref()?;
    assert_eq!(words.len(), f.set.word_count(), "restored words of another layout");
    let mut engine = Engine::new(&f.project, &[] as &[project::Watched]);
    engine.restore_retained(words);
    let plan = engine.restore_retained_variables(&startup.variables);
    let mut captured = Vec::new();
    f.set.capture(engine.vm().mem.words(), &mut captured);
    let layout = engine.retained_variables();
    let mut copy = Vec::new();
    layout.copy(engine.vm().vars(), &mut copy);
    let records = layout.records();
    let variables =
        records.iter().map(|r| (r.name.clone(), layout.record_in(r, &copy).to_vec())).collect();
    // A version 3 file restores its element records into an array record each.
    assert!(startup.version < format::VERSION || plan.restore.len() <= records.len());
    Some(Held { words: captured, variables })
}
