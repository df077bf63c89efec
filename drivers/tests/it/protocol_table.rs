//! Actidyn and ACUTROL rate-table command languages, both directions.
#![allow(clippy::unwrap_used)]

use bench_drivers::protocol::actidyn::{
    self, encode_commands, encode_replies, parse_command_line, parse_reply_line, Axis, Command,
    Mode, Reply, ReplyBody, Value,
};
use bench_drivers::protocol::acutrol::{self, Encoding, Form};
use proptest::prelude::*;

const A1: Axis = Axis::Number(1);

#[test]
fn actidyn_commands_byte_exact() {
    let cases: Vec<(Command, &[u8])> = vec![
        (Command::Remote, b"RMT 0\n"),
        (Command::Local, b"LOC 0\n"),
        (Command::ClearAlarms, b"ALC 0\n"),
        (Command::SetMode { axis: A1, mode: Mode::ServoOn }, b"MOD 1,1\n"),
        (Command::SetMode { axis: Axis::All, mode: Mode::Off }, b"MOD &,OFF\n"),
        (Command::SetMode { axis: A1, mode: Mode::Rate }, b"MOD 1,RAT\n"),
        (Command::SetMode { axis: A1, mode: Mode::Stop }, b"MOD 1,STP\n"),
        (Command::QueryMode { axis: Axis::All }, b"MOD &,?\n"),
        (Command::Rate { axis: A1, rate_deg_s: 0.0, accel_deg_s2: 5.0 }, b"RAT 1,0,5\n"),
        (
            Command::Rate { axis: A1, rate_deg_s: -0.16666666666666666, accel_deg_s2: 1.0 },
            b"RAT 1,-0.16666666666666666,1\n",
        ),
        (Command::Position { axis: A1, position_deg: 90.0, rate_deg_s: 10.5 }, b"POS 1,90,10.5\n"),
        (
            Command::Sine { axis: A1, amplitude_deg: 1.0, frequency_hz: 0.5, phase_deg: 0.0 },
            b"SIN 1,1,0.5,0\n",
        ),
        (Command::QueryPosition { axis: A1 }, b"POS 1,?\n"),
        (Command::QueryPrv { axis: A1 }, b"PRV 1,?\n"),
    ];
    let mut dec = actidyn::CommandDecoder::new();
    for (c, bytes) in &cases {
        assert_eq!(c.encode().unwrap(), *bytes, "{c:?}");
        dec.push(bytes);
        assert_eq!(dec.next_message().unwrap().unwrap(), vec![*c]);
    }
    let chained =
        [Command::Remote, Command::ClearAlarms, Command::SetMode { axis: A1, mode: Mode::Rate }];
    assert_eq!(encode_commands(&chained).unwrap(), b"RMT 0:ALC 0:MOD 1,RAT\n");
    assert!(Command::Rate { axis: A1, rate_deg_s: f64::NAN, accel_deg_s2: 1.0 }.encode().is_err());
}

#[test]
fn actidyn_parser_is_lenient_on_case_and_space() {
    assert_eq!(
        parse_command_line(b" rat 1, -2.5 ,1e1 : prv & ,? ").unwrap(),
        vec![
            Command::Rate { axis: A1, rate_deg_s: -2.5, accel_deg_s2: 10.0 },
            Command::QueryPrv { axis: Axis::All }
        ]
    );
}

#[test]
fn actidyn_replies_byte_exact() {
    let prv = Command::QueryPrv { axis: A1 };
    let modq = Command::QueryMode { axis: Axis::All };
    let rat = Command::Rate { axis: A1, rate_deg_s: 1.0, accel_deg_s2: 1.0 };
    let replies = vec![
        Reply::ack(&Command::ClearAlarms),
        Reply::values(&prv, vec![Value::Number(12.5), Value::Number(-0.25), Value::Number(0.0)]),
        Reply::values(&modq, vec![Value::Mode(Mode::Rate), Value::Mode(Mode::Off)]),
        Reply::error(&rat, 12, "drive not ready, servo off"),
    ];
    let bytes = encode_replies(&replies).unwrap();
    assert_eq!(
        bytes,
        b"ALC 0,0:PRV 1,3,12.5,-0.25,0:MOD &,2,RAT,OFF:RAT 1,ERR,12,drive not ready, servo off\n"
    );
    let mut dec = actidyn::ReplyDecoder::new();
    dec.push(&bytes);
    let got = dec.next_message().unwrap().unwrap();
    assert_eq!(got, replies);
    assert!(got[0].answers(&Command::ClearAlarms));
    assert!(got[1].answers(&prv));
    let p = got[1].prv().unwrap();
    assert_eq!((p.position_deg, p.rate_deg_s, p.accel_deg_s2), (12.5, -0.25, 0.0));
    assert_eq!(got[2].modes().unwrap(), vec![Mode::Rate, Mode::Off]);
    assert!(matches!(got[3].body, ReplyBody::Error { code: 12, .. }));
    assert!(Reply::error(&rat, 1, "a:b").to_text().is_err());
}

#[test]
fn actidyn_reply_errors_carry_stream_offsets() {
    let mut dec = actidyn::ReplyDecoder::new();
    // Mid-line start, then a count that does not match, then a good line, split anywhere.
    dec.push(b"5,0\nPRV 1,3,1,2\nPOS 1,1,");
    let e = dec.next_message().unwrap().unwrap_err();
    assert_eq!(e.offset, 0);
    let e = dec.next_message().unwrap().unwrap_err();
    // "PRV 1,3,1,2" starts at 4; the count is at 4 + 6.
    assert_eq!(e.offset, 10);
    assert!(dec.next_message().is_none());
    dec.push(b"45.5\n");
    assert_eq!(dec.next_message().unwrap().unwrap()[0].position_deg(), Some(45.5));
    // Bad number in a chained command line: offset within the line.
    let e = parse_command_line(b"ALC 0:RAT 1,x,5").unwrap_err();
    assert_eq!((e.offset, e.received.as_slice()), (12, &b"x"[..]));
    let e = parse_reply_line(b"PRV 1,1,inf").unwrap_err();
    assert_eq!(e.offset, 8);
    assert!(parse_command_line(b"FOO 1").is_err());
    assert!(parse_command_line(b"PRV 1,3").is_err());
    assert!(parse_command_line(&[0xFF, b'\n']).is_err());
}

/// Issue 17: with `acutrol_short_form` only the short forms the public client showed (`:M:R`,
/// `:D:R`, `:R:R`, `:R:P`) are written; the others stay long (an independent peer that knows
/// only those refused `:U:L ON`). The controller-side parser still reads any abbreviation.
#[test]
fn issue17_acutrol_short_form_only_where_known() {
    use acutrol::Command as C;
    let short = Encoding { form: Form::Short, decimals: 3 };
    let known: Vec<bool> = [
        C::Lockout(true),
        C::InterlockOpen(1),
        C::InterlockReset(1),
        C::InterlockClose(1),
        C::ModeOff(1),
        C::ModeRate(1),
        C::ModePosition(1),
        C::DemandRate { axis: 1, rate_deg_s: 1.0 },
        C::DemandPosition { axis: 1, position_deg: 1.0 },
        C::ReadRate(1),
        C::ReadPosition(1),
    ]
    .iter()
    .map(|c| {
        let long = Encoding { form: Form::Long, ..short };
        let written_short = c.encode(short).unwrap() != c.encode(long).unwrap();
        assert_eq!(written_short, c.has_known_short_form(), "{c:?}");
        written_short
    })
    .collect();
    assert_eq!(known, [false, false, false, false, false, true, false, true, false, true, true]);
    let mut dec = acutrol::CommandDecoder::new();
    for (line, c) in [
        (&b":U:L ON\r\n"[..], C::Lockout(true)),
        (b":I:O 1\r\n", C::InterlockOpen(1)),
        (b":M:O 1\r\n", C::ModeOff(1)),
        (b":D:P 1, 090.000\r\n", C::DemandPosition { axis: 1, position_deg: 90.0 }),
    ] {
        dec.push(line);
        assert_eq!(dec.next_message().unwrap().unwrap(), c);
    }
}

#[test]
fn acutrol_commands_byte_exact() {
    use acutrol::Command as C;
    let long3 = Encoding { form: Form::Long, decimals: 3 };
    let short3 = Encoding { form: Form::Short, decimals: 3 };
    let cases: Vec<(C, &[u8], &[u8])> = vec![
        (C::Lockout(true), b":utility:lockout on\r\n", b":utility:lockout on\r\n"),
        (C::InterlockOpen(1), b":interlock:open 1\r\n", b":interlock:open 1\r\n"),
        (C::InterlockReset(1), b":interlock:reset 1\r\n", b":interlock:reset 1\r\n"),
        (C::InterlockClose(1), b":interlock:close 1\r\n", b":interlock:close 1\r\n"),
        (C::ModeOff(1), b":mode:off 1\r\n", b":mode:off 1\r\n"),
        (C::ModeRate(1), b":mode:rate 1\r\n", b":M:R 1\r\n"),
        (C::ModePosition(2), b":mode:position 2\r\n", b":mode:position 2\r\n"),
        (
            C::DemandRate { axis: 1, rate_deg_s: 10.0 },
            b":demand:rate 1, 010.000\r\n",
            b":D:R 1, 010.000\r\n",
        ),
        (
            C::DemandRate { axis: 1, rate_deg_s: -0.5 },
            b":demand:rate 1, -00.500\r\n",
            b":D:R 1, -00.500\r\n",
        ),
        (
            C::DemandPosition { axis: 1, position_deg: 90.0 },
            b":demand:position 1, 090.000\r\n",
            b":demand:position 1, 090.000\r\n",
        ),
        (C::ReadRate(1), b":read:rate 1\r\n", b":R:R 1\r\n"),
        (C::ReadPosition(1), b":read:position 1\r\n", b":R:P 1\r\n"),
    ];
    let mut dec = acutrol::CommandDecoder::new();
    for (c, long, short) in &cases {
        assert_eq!(c.encode(long3).unwrap(), *long, "{c:?}");
        assert_eq!(c.encode(short3).unwrap(), *short, "{c:?}");
        dec.push(long);
        dec.push(short);
        assert_eq!(dec.next_message().unwrap().unwrap(), *c);
        assert_eq!(dec.next_message().unwrap().unwrap(), *c);
    }
    // Default: 6 decimals, long form.
    assert_eq!(
        C::DemandRate { axis: 1, rate_deg_s: 10.0 / 60.0 }.encode(Encoding::default()).unwrap(),
        b":demand:rate 1, 000.166667\r\n"
    );
    // Any keyword prefix, any case.
    assert_eq!(acutrol::parse_command(b":MO:RAT 1").unwrap(), C::ModeRate(1));
}

#[test]
fn acutrol_replies_and_errors() {
    let mut dec = acutrol::ReplyDecoder::new();
    dec.push(b"OK\r\n010.500\r\nERR axis 3 not present\r\nK\r\n");
    assert_eq!(dec.next_message().unwrap().unwrap(), acutrol::Reply::Ok);
    assert_eq!(dec.next_message().unwrap().unwrap(), acutrol::Reply::Value(10.5));
    assert_eq!(
        dec.next_message().unwrap().unwrap(),
        acutrol::Reply::Error("axis 3 not present".into())
    );
    let e = dec.next_message().unwrap().unwrap_err();
    assert_eq!((e.offset, e.received.as_slice()), (37, &b"K"[..]));
    assert_eq!(
        acutrol::Reply::Value(-1.25).encode(Encoding::default()).unwrap(),
        b"-01.250000\r\n"
    );
    // Command errors: offsets inside the line.
    let e = acutrol::parse_command(b":demand:rate 1, abc").unwrap_err();
    assert_eq!(e.offset, 15);
    let e = acutrol::parse_command(b":mode:sideways 1").unwrap_err();
    assert_eq!(e.offset, 0);
    assert!(acutrol::parse_command(b":read:rate x").is_err());
    assert!(acutrol::parse_command(b":read:rate 1, 5").is_err());
}

fn any_axis() -> impl Strategy<Value = Axis> {
    prop_oneof![Just(Axis::All), (0u8..=9).prop_map(Axis::Number)]
}

fn num() -> impl Strategy<Value = f64> {
    -1e6f64..1e6
}

fn any_command() -> impl Strategy<Value = Command> {
    let mode = prop_oneof![
        Just(Mode::ServoOn),
        Just(Mode::Off),
        Just(Mode::Position),
        Just(Mode::Rate),
        Just(Mode::Sine),
        Just(Mode::Stop)
    ];
    prop_oneof![
        Just(Command::Remote),
        Just(Command::Local),
        Just(Command::ClearAlarms),
        (any_axis(), mode).prop_map(|(axis, mode)| Command::SetMode { axis, mode }),
        any_axis().prop_map(|axis| Command::QueryMode { axis }),
        any_axis().prop_map(|axis| Command::QueryPosition { axis }),
        any_axis().prop_map(|axis| Command::QueryPrv { axis }),
        (any_axis(), num(), num()).prop_map(|(axis, a, b)| Command::Rate {
            axis,
            rate_deg_s: a,
            accel_deg_s2: b
        }),
        (any_axis(), num(), num()).prop_map(|(axis, a, b)| Command::Position {
            axis,
            position_deg: a,
            rate_deg_s: b
        }),
        (any_axis(), num(), num(), num()).prop_map(|(axis, a, b, c)| Command::Sine {
            axis,
            amplitude_deg: a,
            frequency_hz: b,
            phase_deg: c
        }),
    ]
}

fn acutrol_command() -> impl Strategy<Value = acutrol::Command> {
    use acutrol::Command as C;
    // Values on the wire have `decimals` digits: generate multiples of 1e-6.
    let v = (-999_999_999i64..999_999_999).prop_map(|k| k as f64 / 1e6);
    prop_oneof![
        any::<bool>().prop_map(C::Lockout),
        any::<u8>().prop_map(C::InterlockOpen),
        any::<u8>().prop_map(C::InterlockReset),
        any::<u8>().prop_map(C::InterlockClose),
        any::<u8>().prop_map(C::ModeOff),
        any::<u8>().prop_map(C::ModeRate),
        any::<u8>().prop_map(C::ModePosition),
        any::<u8>().prop_map(C::ReadRate),
        any::<u8>().prop_map(C::ReadPosition),
        (any::<u8>(), v.clone()).prop_map(|(axis, rate_deg_s)| C::DemandRate { axis, rate_deg_s }),
        (any::<u8>(), v).prop_map(|(axis, position_deg)| C::DemandPosition { axis, position_deg }),
    ]
}

proptest! {
    #[test]
    fn actidyn_command_roundtrip(cmds in proptest::collection::vec(any_command(), 1..5)) {
        let line = encode_commands(&cmds).unwrap();
        let mut dec = actidyn::CommandDecoder::new();
        dec.push(&line);
        prop_assert_eq!(dec.next_message().unwrap().unwrap(), cmds);
    }

    #[test]
    fn actidyn_reply_roundtrip(cmd in any_command(), values in proptest::collection::vec(num(), 0..4), code in any::<u16>(), msg in "[a-zA-Z0-9]([a-zA-Z0-9 ,]{0,20}[a-zA-Z0-9])?", err in any::<bool>()) {
        let r = if err {
            Reply::error(&cmd, code, msg)
        } else {
            Reply::values(&cmd, values.into_iter().map(Value::Number).collect())
        };
        // MOD replies read tokens as modes: numbers there are modes or fail, skip those.
        prop_assume!(cmd.mnemonic() != actidyn::Mnemonic::Mod || err);
        let bytes = encode_replies(std::slice::from_ref(&r)).unwrap();
        prop_assert_eq!(parse_reply_line(bytes.strip_suffix(b"\n").unwrap()).unwrap(), vec![r]);
    }

    #[test]
    fn acutrol_roundtrip(c in acutrol_command(), short in any::<bool>()) {
        let enc = Encoding { form: if short { Form::Short } else { Form::Long }, decimals: 6 };
        let mut dec = acutrol::CommandDecoder::new();
        dec.push(&c.encode(enc).unwrap());
        prop_assert_eq!(dec.next_message().unwrap().unwrap(), c);
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut a = actidyn::CommandDecoder::new();
        a.push(&bytes);
        while a.next_message().is_some() {}
        let mut b = actidyn::ReplyDecoder::new();
        b.push(&bytes);
        while b.next_message().is_some() {}
        let mut c = acutrol::CommandDecoder::new();
        c.push(&bytes);
        while c.next_message().is_some() {}
        let mut d = acutrol::ReplyDecoder::new();
        d.push(&bytes);
        while d.next_message().is_some() {}
    }
}
