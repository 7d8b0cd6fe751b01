//! A byte stream from an OPC UA client to the server's TCP socket (`[opcua] listen`,
//! docs/OPCUA.md), read as the OPC UA stack's server reads it (async-opcua's
//! `opcua_server::transport::tcp`, written out here: its transport is not public) with the
//! limits plcd's server runs with: the stack's `TcpCodec` frames it into Hello and chunks, the
//! chunks of the None security policy go through the secure channel
//! (`verify_and_remove_security_server`), the sequence numbers, the negotiated chunk count and
//! `Chunker::validate_chunks`, and each complete message is decoded by its encoding id as the
//! server decodes it (`Chunker::decode` into a `RequestMessage`: every service's request). The
//! stream stops where the server would close the connection, or where it asks for another
//! policy than None (its crypto is not fuzzed here). Unlike the server's channel, the target's
//! has no id, so the chunks' channel ids are not compared.
//!
//! What must hold: no chunk, message, array or string larger than the limits; a decoded request
//! encodes to as many bytes as its `byte_len` says, no more than it was decoded from, and those
//! decode to an equal request (the stack's encoding round-trips), but for a DateTime outside
//! 1601..9999, which the stack decodes as sent and encodes as the range's end: then the
//! request is the same from its second decoding on (`tests/fuzz/crashes/opcua/`). Then plcd's own code on what
//! the client sent: every value of a Write and every argument of a Call, and each element of
//! an array of them, is converted by `services::opcua::values::written` for every IEC type
//! plcd serves, which must refuse it as `BadTypeMismatch` or `BadOutOfRange` or give a text
//! that `plcctl set`'s parser takes back to the same text, and to the variant written when
//! served again (`values::slot_variant`; within what the type holds: a `DATE` drops the time of
//! day, a `DT` the fraction of a second); the one exception is an enumeration's number that no
//! value of it has, written as that number, which `set` refuses by design (`BadOutOfRange`,
//! docs/OPCUA.md). `PLC.Reset`'s `Cold` is decided in the node manager's `call` (a slice
//! pattern, no conversion): here it is one more argument through `written`.

use std::io::Cursor;
use std::path::Path;
use std::sync::{Arc, OnceLock};

use bytes::BytesMut;
use opcua::core::comms::chunker::Chunker;
use opcua::core::comms::message_chunk::{MessageChunk, MessageChunkType, MessageIsFinalType};
use opcua::core::comms::secure_channel::{Role, SecureChannel};
use opcua::core::comms::security_header::SecurityHeader;
use opcua::core::comms::sequence_number::SequenceNumberHandle;
use opcua::core::comms::tcp_codec::{Message, TcpCodec};
use opcua::core::{Message as _, RequestMessage};
use opcua::crypto::{CertificateStore, SecurityPolicy};
use opcua::sync::RwLock;
use opcua::types::{
    BinaryDecodable, BinaryEncodable, Context, ContextOwned, DecodingOptions, NamespaceMap, NodeId,
    StatusCode, TypeLoaderCollection, Variant,
};
use plcd::config::OpcuaConfig;
use plcd::services::opcua::{front, values};
use plcd::value::{self, Calendar, Elem, ValueType};
use tokio_util::codec::Decoder;

/// The decoding limits of plcd's server: `[opcua] max_request_bytes` at its default (the
/// server's builder sets the stack's `max_message_size` to it) and the stack's own defaults for
/// the rest, which plcd leaves as they are (`services::opcua::server::builder`).
pub fn options() -> DecodingOptions {
    DecodingOptions {
        max_message_size: OpcuaConfig::default().max_request_bytes as usize,
        ..DecodingOptions::default()
    }
}

/// The IEC types a client may write, one of each kind plcd serves (docs/OPCUA.md, "Types").
pub fn types() -> &'static [ValueType] {
    static TYPES: OnceLock<Vec<ValueType>> = OnceLock::new();
    TYPES.get_or_init(|| {
        let mut types = vec![ValueType::Bool];
        for e in [Elem::I8, Elem::I16, Elem::I32, Elem::I64] {
            types.push(ValueType::Signed(e));
        }
        for e in [Elem::U8, Elem::U16, Elem::U32, Elem::U64] {
            types.push(ValueType::Unsigned(e));
        }
        types.extend([ValueType::Real(Elem::F32), ValueType::Real(Elem::F64), ValueType::Time]);
        types.extend(Calendar::ALL.map(ValueType::Calendar));
        types.extend([ValueType::Char, ValueType::WChar]);
        types.extend([ValueType::String { cap: 80 }, ValueType::WString { cap: 80 }]);
        let values = |names: &[(&str, i64)]| -> Vec<(String, i64)> {
            names.iter().map(|(n, v)| (n.to_string(), *v)).collect()
        };
        types.push(ValueType::Enum {
            type_name: "Color".into(),
            values: values(&[("Red", 0), ("Green", 1), ("Blue", 7)]),
            base: Elem::I32,
        });
        types.push(ValueType::Enum {
            type_name: "Mode".into(),
            values: values(&[("Off", -1), ("Auto", 300)]),
            base: Elem::I16,
        });
        types
    })
}

/// The secure channel's certificate store: none (the None policy needs no certificate).
fn certificates() -> Arc<RwLock<CertificateStore>> {
    static STORE: OnceLock<Arc<RwLock<CertificateStore>>> = OnceLock::new();
    STORE
        .get_or_init(|| {
            Arc::new(RwLock::new(CertificateStore::new(Path::new("/nonexistent/plcd-fuzz-pki"))))
        })
        .clone()
}

pub fn run(data: &[u8]) {
    requests(data, check);
}

/// What the server's public side (`services::opcua::front`, with `[opcua]`'s default limits)
/// lets through of `data`, all arriving at once: whole chunks, none longer than
/// `max_request_bytes`, no message longer either, at most `max_requests_per_second` messages.
fn through_the_front(data: &[u8]) -> &[u8] {
    let limits = front::Limits::of(&OpcuaConfig::default());
    let (passed, _) = front::passed(data, &limits);
    assert!(passed <= data.len());
    let (mut at, mut message, mut requests) = (0, 0u64, 0u32);
    while at < passed {
        let size = u32::from_le_bytes(data[at + 4..at + 8].try_into().expect("4 bytes"));
        assert!(size >= 8 && size <= limits.message_bytes, "a chunk of {size} passed");
        if matches!(&data[at..at + 3], b"MSG" | b"OPN" | b"CLO") {
            message += u64::from(size);
            assert!(message <= u64::from(limits.message_bytes), "a message of {message} passed");
            match data[at + 3] {
                b'C' => {}
                b'A' => message = 0,
                _ => {
                    message = 0;
                    requests += 1;
                }
            }
        } else {
            requests += 1;
        }
        at += size as usize;
    }
    assert_eq!(at, passed, "the front passed part of a chunk");
    assert!(requests <= limits.requests_per_second, "{requests} requests at once");
    &data[..passed]
}

/// Reads `data` as the server reads a connection's bytes, calling `each` with the channel and
/// every request the server would handle, and the bytes of the chunk bodies it came from.
pub fn requests(data: &[u8], mut each: impl FnMut(&SecureChannel, &RequestMessage, usize)) {
    let options = options();
    let mut codec = TcpCodec::new(options.clone());
    // The stack sees what the front lets through.
    let mut buf = BytesMut::from(through_the_front(data));
    // The Hello first (`TcpConnector::connect_inner`).
    let Ok(Some(Message::Hello(hello))) = codec.decode(&mut buf) else { return };
    let url = hello.endpoint_url.value().as_ref().map_or(0, String::len);
    assert!(url <= options.max_string_length, "an endpoint URL of {url} bytes");
    if !hello.is_valid_buffer_sizes() || hello.protocol_version > 0 {
        return;
    }
    // The chunk count the server acknowledges: the smaller, 0 being no limit.
    let max_chunks = match (options.max_chunk_count, hello.max_chunk_count as usize) {
        (server, 0) => server,
        (0, client) => client,
        (server, client) => server.min(client),
    };
    let context =
        ContextOwned::new(NamespaceMap::new(), TypeLoaderCollection::new(), options.clone());
    let mut channel =
        SecureChannel::new(certificates(), Role::Server, Arc::new(RwLock::new(context)));
    let mut sequence = SequenceNumberHandle::new(true);
    let mut pending: Vec<MessageChunk> = Vec::new();
    // Then chunks (`TcpTransport::process_message`), until the server would close.
    loop {
        let Ok(Some(message)) = codec.decode(&mut buf) else { return };
        let Message::Chunk(chunk) = message else { return };
        assert!(chunk.data.len() <= options.max_message_size, "a chunk of {}", chunk.data.len());
        match next_message(&mut channel, &mut sequence, &mut pending, max_chunks, chunk) {
            Step::More => {}
            Step::Close => return,
            Step::Request(request, size) => {
                pending.clear();
                each(&channel, &request, size);
            }
            Step::Refused(recoverable) => {
                pending.clear();
                if !recoverable {
                    return;
                }
            }
        }
    }
}

enum Step {
    /// An intermediate chunk, or a final error chunk that drops the message.
    More,
    /// A complete request and the bytes of its chunks' bodies.
    Request(Box<RequestMessage>, usize),
    /// A message refused: with a service fault if recoverable, else closing the connection.
    Refused(bool),
    /// Not a chunk the server reads on (or one of another policy's crypto).
    Close,
}

fn next_message(
    channel: &mut SecureChannel,
    sequence: &mut SequenceNumberHandle,
    pending: &mut Vec<MessageChunk>,
    max_chunks: usize,
    chunk: MessageChunk,
) -> Step {
    let Ok(header) = chunk.message_header(&channel.decoding_options()) else { return Step::Close };
    if header.is_final == MessageIsFinalType::FinalError {
        pending.clear();
        return Step::More;
    }
    // Only the None policy: an OpenSecureChannel asking for another goes to its crypto.
    if header.message_type == MessageChunkType::OpenSecureChannel {
        let Ok(info) = chunk.chunk_info(channel) else { return Step::Close };
        let SecurityHeader::Asymmetric(security) = &info.security_header else {
            return Step::Close;
        };
        if SecurityPolicy::from_uri(security.security_policy_uri.as_ref()) != SecurityPolicy::None {
            return Step::Close;
        }
    }
    let refused = |e: opcua::types::Error| Step::Refused(e.full_context().is_some());
    let chunk = match channel.verify_and_remove_security_server(chunk.data) {
        Ok(chunk) => chunk,
        Err(e) => return refused(e),
    };
    if max_chunks > 0 && pending.len() == max_chunks {
        return Step::Refused(false);
    }
    let info = match chunk.chunk_info(channel) {
        Ok(info) => info,
        Err(e) => return refused(e),
    };
    if let Err(e) = sequence.validate_and_increment(info.sequence_header.sequence_number) {
        return refused(e);
    }
    pending.push(chunk);
    if header.is_final == MessageIsFinalType::Intermediate {
        return Step::More;
    }
    let mut size = 0;
    for chunk in pending.iter() {
        assert!(chunk.data.len() <= channel.decoding_options().max_message_size);
        size += chunk.chunk_info(channel).expect("read before").body_length;
    }
    assert!(pending.len() <= max_chunks || max_chunks == 0, "{} chunks", pending.len());
    if let Err(e) = Chunker::validate_chunks(channel, pending) {
        return refused(e);
    }
    match Chunker::decode::<RequestMessage>(pending, channel, None) {
        Ok(request) => Step::Request(Box::new(request), size),
        Err(e) => refused(e),
    }
}

/// The invariants on a decoded request; `size`: the bytes of the bodies it was decoded from.
fn check(channel: &SecureChannel, request: &RequestMessage, size: usize) {
    let options = channel.decoding_options();
    let owned = channel.context();
    let ctx = owned.context();
    let (bytes, again) = round_trip(request, &ctx);
    assert_eq!(bytes.len() - id_len(request, &ctx), request.byte_len(&ctx), "byte_len");
    assert!(bytes.len() <= size, "{}: {} bytes from {size}", request.type_name(), bytes.len());
    // The request as first decoded, but for a DateTime before 1601 or after 9999, which the
    // stack decodes as sent and encodes as the range's end (OPC UA Part 6, 5.2.2.5); NaN is
    // not equal to itself, so then the texts must be equal.
    let same =
        |a: &RequestMessage, b: &RequestMessage| a == b || format!("{a:?}") == format!("{b:?}");
    assert!(
        same(request, &again) || out_of_range_date(&format!("{request:?}")),
        "a request changed by a round trip:\n{request:?}\n{again:?}"
    );
    // From then on the same value. Not the same bytes: a DateTime of i64::MAX ticks (after
    // 9999) decodes as 9999-12-31 23:59:59, which encodes as its own ticks.
    let (_, third) = round_trip(&again, &ctx);
    assert!(
        same(&again, &third),
        "a request changed by a second round trip:\n{again:?}\n{third:?}"
    );

    let most = options.max_array_length;
    let arrays = match request {
        RequestMessage::Read(r) => r.nodes_to_read.as_ref().map_or(0, Vec::len),
        RequestMessage::Write(r) => r.nodes_to_write.as_ref().map_or(0, Vec::len),
        RequestMessage::Call(r) => r.methods_to_call.as_ref().map_or(0, Vec::len),
        RequestMessage::Browse(r) => r.nodes_to_browse.as_ref().map_or(0, Vec::len),
        RequestMessage::CreateMonitoredItems(r) => r.items_to_create.as_ref().map_or(0, Vec::len),
        RequestMessage::ActivateSession(r) => {
            r.client_software_certificates.as_ref().map_or(0, Vec::len)
        }
        _ => 0,
    };
    assert!(arrays <= most, "an array of {arrays} elements");

    // plcd's code on the values a client sends.
    let mut variants: Vec<&Variant> = Vec::new();
    match request {
        RequestMessage::Write(r) => {
            for w in r.nodes_to_write.iter().flatten() {
                variants.extend(w.value.value.as_ref());
            }
        }
        RequestMessage::Call(r) => {
            for m in r.methods_to_call.iter().flatten() {
                variants.extend(m.input_arguments.iter().flatten());
            }
        }
        _ => {}
    }
    for variant in variants {
        written(variant, &options);
        if let Variant::Array(array) = variant {
            assert!(array.values.len() <= most, "an array of {}", array.values.len());
            for element in &array.values {
                written(element, &options);
            }
        }
    }
}

/// A request encoded as the stack encodes a message (its encoding id, then the request), and
/// decoded again from those bytes, which it must be, to their end.
fn round_trip(request: &RequestMessage, ctx: &Context<'_>) -> (Vec<u8>, RequestMessage) {
    let mut bytes = Vec::new();
    let id = request.type_id();
    id.encode(&mut bytes, ctx).expect("a node id encodes");
    request.encode(&mut bytes, ctx).expect("a decoded request encodes");
    let mut stream = Cursor::new(&bytes[..]);
    let again = NodeId::decode(&mut stream, ctx).expect("the node id decodes again");
    assert_eq!(again, id);
    let object = again.as_object_id().expect("an object id");
    let again = RequestMessage::decode_by_object_id(&mut stream, object, ctx)
        .unwrap_or_else(|e| panic!("{} does not decode again: {e}", request.type_name()));
    assert_eq!(stream.position() as usize, bytes.len(), "bytes left after {}", request.type_name());
    (bytes, again)
}

/// The bytes of a request's encoding id.
fn id_len(request: &RequestMessage, ctx: &Context<'_>) -> usize {
    request.type_id().byte_len(ctx)
}

/// Whether a value's debug text holds a DateTime that OPC UA's binary encoding cannot: before
/// 1601-01-01 (a year with a sign or below 1601) or after 9999-12-31 23:59:59.
fn out_of_range_date(debug: &str) -> bool {
    debug.split("date_time: ").skip(1).any(|at| {
        let year: Option<u32> = at.get(..4).and_then(|y| y.parse().ok());
        at.starts_with(['+', '-'])
            || year.is_none_or(|y| y < 1601)
            || (at.starts_with("9999-12-31T23:59:59") && !at.starts_with("9999-12-31T23:59:59Z"))
    })
}

/// A variant as written to a variable of every type: refused as `set` would never see it, or a
/// text `set` reads back to the same text and to the variant written (within the type's
/// precision).
fn written(variant: &Variant, options: &DecodingOptions) {
    if let Variant::String(s) = variant {
        assert!(s.value().as_ref().is_none_or(|s| s.len() <= options.max_string_length));
    }
    for ty in types() {
        let text = match values::written(ty, variant) {
            Err(StatusCode::BadTypeMismatch | StatusCode::BadOutOfRange) => continue,
            Err(other) => panic!("{ty:?} of {variant:?}: {other}"),
            Ok(plcd_ipc::Value::Text(text)) => text,
            Ok(other) => panic!("{ty:?} of {variant:?}: not a text: {other:?}"),
        };
        let back = match ty {
            ValueType::String { .. } => {
                value::parse_string(&text, u32::MAX).map(|b| value::format_string(&b))
            }
            ValueType::WString { .. } => {
                value::parse_wstring(&text, u32::MAX).map(|u| value::format_wstring(&u))
            }
            _ => value::parse(ty, &text).map(|slot| {
                read_back(ty, variant, slot);
                value::format(ty, slot)
            }),
        };
        match (back, ty) {
            (Ok(back), _) => assert_eq!(back, text, "{ty:?} of {variant:?}: read back"),
            // `set` refuses a number no value of the enumeration has.
            (Err(_), ValueType::Enum { values, .. }) => {
                let n: i64 = text.parse().unwrap_or_else(|_| panic!("{ty:?}: {text:?}"));
                assert!(values.iter().all(|(_, v)| *v != n), "{ty:?}: {text:?} refused");
            }
            (Err(e), _) => panic!("{ty:?} of {variant:?}: {text:?} refused: {e}"),
        }
    }
}

/// The slot `set` stores for a variant written to a `ty`, served again as the server serves
/// it: the same variant, but for what the type cannot hold (a `DATE`'s time of day, a `DT`'s
/// fraction of a second, a Duration's fraction of a nanosecond, a NaN's payload).
fn read_back(ty: &ValueType, variant: &Variant, slot: u64) {
    let again = values::slot_variant(ty, slot);
    match (ty, variant) {
        (ValueType::Calendar(calendar), Variant::DateTime(at)) => {
            let Variant::DateTime(back) = &again else { panic!("{ty:?}: {again:?}") };
            // Ticks of 100 ns the type drops.
            let unit = match calendar.kind() {
                value::CalendarKind::Date => 864_000_000_000,
                _ if calendar.is_long() => 1,
                _ => 10_000_000,
            };
            let (at, back) = (at.checked_ticks(), back.checked_ticks());
            assert!(back <= at && at - back < unit, "{ty:?}: {at} ticks served as {back}");
        }
        (ValueType::Time | ValueType::Calendar(_), _) => {}
        (_, Variant::Float(f)) if f.is_nan() => {
            assert!(matches!(again, Variant::Float(b) if b.is_nan()))
        }
        (_, Variant::Double(f)) if f.is_nan() => {
            assert!(matches!(again, Variant::Double(b) if b.is_nan()))
        }
        _ => assert_eq!(again, *variant, "{ty:?}: written and served again"),
    }
}
