//! The client's retry rules (docs/protocol.md §6 rule 3, §7) against the simulated robot behind
//! a scripted line: which failures each layer reads past (noise: a corrupted telegram, a reply
//! that passed the check value but does not parse) and which it reports at once (a robot that
//! takes no ENQ); and `stop_at_once`, whose STOP must be seen executed in the status.
//!
//! Every expected count comes from the protocol's constants (`N_TX`, `N_ENQ`, `T_ENQ`,
//! `RetryPolicy::request_sessions`, `CONFIRMING_READS`), not from a run of the client.

use std::time::Duration;

use asea_protocol::client::CONFIRMING_READS;
use asea_protocol::clock::{Clock, VirtualClock};
use asea_protocol::command::START_INPUT;
use asea_protocol::frame::{ACK, ENQ, EOT, Frame, STX, telegram_digest};
use asea_protocol::link::{Paced, Peer};
use asea_protocol::session::{N_ENQ, N_TX, T_ENQ};
use asea_protocol::{Client, ClientConfig, Control, Error, Instruction, LinkError, Robot, State};

/// Telegram codes the script looks for (docs/protocol.md §5).
const STOP: u8 = 0x0C;
const ENQUIRE: u8 = 0x06;
const STORE_CONTROL: u8 = 0x09;
const REPLY_ENQUIRE: u8 = 0x86;
const REPLY_READ_BACK: u8 = 0x8D;
const REPLY_PROGRAM_INFO: u8 = 0x8F;
const SET_BASE_SPEED: u8 = 0x0A;
const DELETE_PROGRAM: u8 = 0x07;
const ACK_ERROR: u8 = 0x0E;

/// A program's wait for the PC's start, and its end.
const WAIT_CONTROL: Control = Control::WaitInput {
    line: START_INPUT,
    on: true,
};
const WAIT_FOR_START: Instruction = Instruction::Control(WAIT_CONTROL);
const END: Instruction = Instruction::Control(Control::End);

/// What the line does to the traffic, each rule a set number of times.
#[derive(Debug, Default)]
struct Script {
    /// Telegrams with this code the line acknowledges to the host itself and never delivers: a
    /// telegram the robot acknowledges and does not execute.
    swallow: Option<(u8, u32)>,
    /// Telegrams of the swallowed code delivered before the swallowing starts.
    swallow_skip: u32,
    /// Sessions in which the STOP telegram reaches the robot (which executes it) and every
    /// answer of the robot after it is lost until the host's EOT.
    mute_after_stop: u32,
    /// ENQUIRE telegrams delivered with a wrong check value (the robot refuses them with NAK).
    corrupt_enquiries: u32,
    /// Reply telegrams with this code that reach the host with an undefined code and a check
    /// value that matches: they pass the one-byte sum and do not parse.
    garble: Option<(u8, u32)>,
    /// The robot falls silent at the host's first ENQ after the session of a STOP.
    silent_after_stop: bool,
    /// ACK_ERROR telegrams the line acknowledges itself and never delivers: the robot's error
    /// stays latched.
    lose_ack_errors: bool,
    /// The robot falls silent at the host's first ENQ after this many more replies with this
    /// code.
    silent_after_replies: Option<(u8, u32)>,
    /// The first telegram with this code is replaced on the line by this other whole telegram,
    /// which the robot acknowledges and executes: a foreign command in place of the host's.
    replace: Option<(u8, Vec<u8>)>,
    /// After this many replies with this code, this many more are replaced on the line by this
    /// whole reply telegram, with its own good check value (a corruption the one-byte sum lets
    /// pass).
    forge_reply: Option<(u8, u32, u32, Vec<u8>)>,
    /// Twins: after this many host telegrams with this code, the next ones (this many) each
    /// reach the robot with a corrupted twin, which the robot executes right after it: the
    /// resent copy of a telegram whose ACK was lost, corrupted so that the one-byte sum still
    /// matches (docs/protocol.md §7.1). Each rule counts the host's telegrams, swallowed or not.
    twins: Vec<Twin>,
}

/// One twin rule of [`Script::twins`].
#[derive(Debug)]
struct Twin {
    code: u8,
    skip: u32,
    count: u32,
    /// What the robot executes as the twin.
    twin: Frame,
}

/// The simulated robot behind a scripted line.
#[derive(Debug)]
struct Line {
    robot: Robot,
    script: Script,
    /// A host telegram being received, held until it is whole.
    held: Vec<u8>,
    /// Bytes the line itself sends to the host.
    forged: Vec<u8>,
    /// The robot's answers are lost until the host's EOT.
    muted: bool,
    /// The robot falls silent at the host's next ENQ.
    fall_silent: bool,
    /// Since when the robot has been silent.
    silent_since: Option<Duration>,
}

impl Line {
    fn new(script: Script) -> Self {
        Line {
            robot: Robot::default(),
            fall_silent: false,
            script,
            held: Vec::new(),
            forged: Vec::new(),
            muted: false,
            silent_since: None,
        }
    }

    /// A whole telegram from the host.
    fn telegram(&mut self, t: Vec<u8>, now: Duration) {
        let code = t[1];
        let mut twin = None;
        for rule in self.script.twins.iter_mut().filter(|r| r.code == code) {
            if rule.skip > 0 {
                rule.skip -= 1;
            } else if rule.count > 0 {
                rule.count -= 1;
                twin = Some(rule.twin.clone());
            }
        }
        self.deliver(t, now);
        if let Some(f) = twin {
            self.robot.machine.execute(&f, now.as_secs_f64());
        }
    }

    /// Delivers a whole host telegram as the script says.
    fn deliver(&mut self, mut t: Vec<u8>, now: Duration) {
        let code = t[1];
        let s = &mut self.script;
        if let Some((c, other)) = &s.replace
            && *c == code
        {
            t = other.clone();
            s.replace = None;
        }
        if let Some((c, n)) = &mut s.swallow
            && *c == code
            && *n > 0
        {
            if s.swallow_skip > 0 {
                s.swallow_skip -= 1;
                self.robot.receive(&t, now);
                return;
            }
            *n -= 1;
            self.forged.push(ACK);
            return;
        }
        if code == ACK_ERROR && s.lose_ack_errors {
            self.forged.push(ACK);
            return;
        }
        if code == ENQUIRE && s.corrupt_enquiries > 0 {
            s.corrupt_enquiries -= 1;
            let cs = t.len() - 1;
            t[cs] ^= 0xFF;
        }
        if code == STOP {
            if s.mute_after_stop > 0 {
                s.mute_after_stop -= 1;
                self.muted = true;
            }
            if s.silent_after_stop {
                self.fall_silent = true;
            }
        }
        self.robot.receive(&t, now);
    }
}

impl Peer for Line {
    fn receive(&mut self, bytes: &[u8], now: Duration) {
        for &b in bytes {
            if self.held.is_empty() && b == ENQ && self.fall_silent {
                self.fall_silent = false;
                self.silent_since = Some(now);
            }
            if self.silent_since.is_some() {
                continue;
            }
            if !self.held.is_empty() || b == STX {
                // The host frames by length (one-byte sum): STX CMD LEN DATA ETX CS.
                self.held.push(b);
                if let Some(&len) = self.held.get(2)
                    && self.held.len() == 3 + usize::from(len) + 2
                {
                    let t = std::mem::take(&mut self.held);
                    self.telegram(t, now);
                }
                continue;
            }
            if b == EOT {
                self.muted = false;
            }
            self.robot.receive(&[b], now);
        }
    }
    fn poll(&mut self, now: Duration) {
        self.robot.poll(now);
    }
    fn take_output(&mut self) -> Vec<u8> {
        let mut out = self.robot.take_output();
        if self.silent_since.is_some() || self.muted {
            out.clear();
        }
        // A whole reply telegram: STX CMD LEN DATA ETX CS.
        if let [STX, code, len, ..] = out[..]
            && out.len() == 3 + usize::from(len) + 2
        {
            if let Some((c, n)) = &mut self.script.garble
                && *c == code
                && *n > 0
            {
                *n -= 1;
                out[1] = code.wrapping_add(1);
                let cs = out.len() - 1;
                out[cs] = out[cs].wrapping_add(1);
            }
            if let Some((c, skip, n, forged)) = &mut self.script.forge_reply
                && *c == code
            {
                if *skip > 0 {
                    *skip -= 1;
                } else if *n > 0 {
                    *n -= 1;
                    out = forged.clone();
                }
            }
            if let Some((c, n)) = &mut self.script.silent_after_replies
                && *c == code
                && *n > 0
            {
                *n -= 1;
                if *n == 0 {
                    self.fall_silent = true;
                }
            }
        }
        let mut bytes = std::mem::take(&mut self.forged);
        bytes.extend(out);
        bytes
    }
    fn deadline(&self) -> Option<Duration> {
        self.robot.deadline()
    }
}

type TestClient = Client<Paced<Line>, VirtualClock>;

fn client(script: Script) -> (TestClient, VirtualClock) {
    let clock = VirtualClock::new();
    let c = Client::with_clock(
        Paced::new(clock.clone(), 9600, Line::new(script)),
        clock.clone(),
        ClientConfig::default(),
    );
    (c, clock)
}

fn robot(c: &TestClient) -> &Robot {
    &c.link().peer.robot
}

/// Sessions one request tries (docs/protocol.md §6 rule 3).
fn request_sessions() -> u32 {
    ClientConfig::default().retry.request_sessions
}

/// One session of `N_ENQ` unanswered ENQs, `T_ENQ` apart, plus the bytes on the wire.
fn one_session() -> Duration {
    T_ENQ * N_ENQ + Duration::from_millis(50)
}

/// A robot in OPERATE, homed, running program 1, which waits for the PC's start (never given):
/// it runs until stopped. Then `script` applies.
fn running(script: Script) -> (TestClient, VirtualClock) {
    let (mut c, clock) = client(Script::default());
    c.operate().unwrap();
    c.sync_home().unwrap();
    c.link_mut().run_for(Duration::from_secs(4));
    let program = [WAIT_FOR_START, END];
    c.upload(1, &program).unwrap();
    c.run_program(1).unwrap();
    assert_eq!(robot(&c).machine.status().state, State::Running);
    c.link_mut().peer.script = script;
    (c, clock)
}

/// The execution count and digest the robot shows (docs/protocol.md §5: every command with an
/// effect advances the count and sets the digest of its CMD, LEN and DATA).
fn executed(c: &TestClient) -> (u16, u16) {
    let s = robot(c).machine.status();
    (s.executed, s.last_digest)
}

/// STOP's digest: code 0x0C, no data.
fn stop_digest() -> u16 {
    telegram_digest(STOP, &[])
}

/// `stop_at_once` sends STOP first and then must see STOPPED in the status (docs/protocol.md
/// §7: `Ok` means executed with its effect). On a clean line the status shows it and STOP is
/// sent once. When the robot acknowledged a STOP it did not execute (the ACK was forged on the
/// line), the status still shows the program running: STOP is sent again, confirmed, and the
/// robot ends STOPPED having executed exactly one STOP.
#[test]
fn stop_at_once_sends_stop_again_only_when_the_status_does_not_show_it_executed() {
    let (mut c, _) = running(Script::default());
    let (before, _) = executed(&c);
    let s = c.stop_at_once().unwrap();
    assert_eq!(s.state, State::Stopped);
    assert_eq!(robot(&c).machine.status().state, State::Stopped);
    assert_eq!(
        executed(&c),
        (before.wrapping_add(1), stop_digest()),
        "one STOP executed on a clean line"
    );

    let (mut c, _) = running(Script {
        swallow: Some((STOP, 1)),
        ..Script::default()
    });
    let (before, _) = executed(&c);
    let s = c.stop_at_once().unwrap();
    assert_eq!(
        c.link().peer.script.swallow,
        Some((STOP, 0)),
        "the STOP was swallowed"
    );
    assert_eq!(s.state, State::Stopped);
    assert_eq!(robot(&c).machine.status().state, State::Stopped);
    assert_eq!(
        executed(&c),
        (before.wrapping_add(1), stop_digest()),
        "the second STOP executed, once"
    );
}

/// A STOP the robot executed whose every acknowledgement was lost: the session fails
/// (`LinkError::Retries` after `N_TX` transmissions, each retransmission re-acknowledged and not
/// executed again, rule 2), but the robot answers ENQ, so the status decides: it shows STOPPED
/// and the call succeeds without a second STOP; likewise for the confirmed STOP.
#[test]
fn a_stop_whose_acknowledgements_are_lost_is_confirmed_by_the_status() {
    let (mut c, _) = running(Script {
        mute_after_stop: 1,
        ..Script::default()
    });
    let (before, _) = executed(&c);
    let s = c.stop_at_once().unwrap();
    assert_eq!(c.link().peer.script.mute_after_stop, 0);
    assert_eq!(s.state, State::Stopped);
    assert_eq!(executed(&c), (before.wrapping_add(1), stop_digest()));
    assert!(c.stats().timeouts >= u64::from(N_TX), "{:?}", c.stats());

    // The same through the confirmed STOP (`Client::stop`, `command_confirmed`): a link failure
    // leaves the fate unknown and the status after it decides (executed once: `Ok`).
    c.link_mut().peer.script.mute_after_stop = 1;
    let (before, _) = executed(&c);
    let s = c.stop().unwrap();
    assert_eq!(c.link().peer.script.mute_after_stop, 0);
    assert_eq!(s.state, State::Stopped);
    assert_eq!(executed(&c), (before.wrapping_add(1), stop_digest()));
}

/// After the STOP, every status read of the confirmation is lost to noise (each ENQUIRE
/// corrupted on the way, NAKed `N_TX` times, in `request_sessions` sessions, for
/// `CONFIRMING_READS` reads): noise is not a silent robot, so the confirmed STOP follows, reads
/// the status clean and returns STOPPED.
#[test]
fn a_stop_whose_status_is_lost_to_noise_falls_back_to_the_confirmed_stop() {
    let lost = CONFIRMING_READS * request_sessions() * N_TX;
    let (mut c, _) = running(Script {
        corrupt_enquiries: lost,
        ..Script::default()
    });
    let s = c.stop_at_once().unwrap();
    assert_eq!(c.link().peer.script.corrupt_enquiries, 0);
    assert_eq!(s.state, State::Stopped);
    assert_eq!(robot(&c).machine.status().state, State::Stopped);
    assert_eq!(executed(&c).1, stop_digest());
}

/// A robot that acknowledges the STOP and then falls silent: the status read after it takes no
/// ENQ, and the call reports that within one session (rule 3: no further session, no confirmed
/// STOP behind it).
#[test]
fn a_robot_silent_after_its_stop_is_reported_within_one_session() {
    let (mut c, clock) = running(Script {
        silent_after_stop: true,
        ..Script::default()
    });
    let e = c.stop_at_once().unwrap_err();
    assert!(
        matches!(e, Error::Link(LinkError::NoResponse { attempts }) if attempts == N_ENQ),
        "{e}"
    );
    assert_eq!(robot(&c).machine.status().state, State::Stopped);
    let silent = clock.now() - c.link().peer.silent_since.unwrap();
    assert!(silent < one_session(), "{silent:?}");
}

/// A request whose first session fails on noise (the ENQUIRE NAKed `N_TX` times: `Retries`)
/// is asked again in a new session and answers.
#[test]
fn a_request_starts_a_new_session_after_a_session_lost_to_noise() {
    let (mut c, _) = client(Script {
        corrupt_enquiries: N_TX,
        ..Script::default()
    });
    let s = c.status().unwrap();
    assert_eq!(c.link().peer.script.corrupt_enquiries, 0);
    assert_eq!(s, robot(&c).machine.status());
}

/// The layers above a request read past a request lost to noise (every session of it answered
/// with a reply that passes the sum and does not parse) and answer from the next reads:
/// `status_agreed`, `program_info` and `confirm_stored` (docs/protocol.md §7: acted on only when
/// answers agree, at most `CONFIRMING_READS` reads).
#[test]
fn agreeing_reads_read_past_a_request_lost_to_noise() {
    let lost = request_sessions();
    let program = [
        Instruction::Control(Control::SetOutput { line: 2, on: true }),
        Instruction::Control(Control::End),
    ];
    let (mut c, _) = client(Script::default());
    c.upload(1, &program).unwrap();

    c.link_mut().peer.script.garble = Some((REPLY_ENQUIRE, lost));
    let s = c.status_agreed().unwrap();
    assert_eq!(c.link().peer.script.garble, Some((REPLY_ENQUIRE, 0)));
    assert_eq!(s, robot(&c).machine.status());

    c.link_mut().peer.script.garble = Some((REPLY_PROGRAM_INFO, lost));
    // Two instructions, the highest numbered 2, two in the whole memory.
    assert_eq!(c.program_info(1).unwrap(), (2, 2, 2));
    assert_eq!(c.link().peer.script.garble, Some((REPLY_PROGRAM_INFO, 0)));

    c.link_mut().peer.script.garble = Some((REPLY_READ_BACK, lost));
    assert!(c.confirm_stored(1, 2, &program[1]).unwrap());
    assert_eq!(c.link().peer.script.garble, Some((REPLY_READ_BACK, 0)));
}

/// A verified upload whose store confirmation and first settling each lose all
/// `CONFIRMING_READS` read-backs to noise (`request_sessions` garbled replies each) settles the
/// instruction again (up to `request_sessions` times) and succeeds with the program stored.
#[test]
fn a_verified_upload_settles_again_after_read_backs_lost_to_noise() {
    let lost = 2 * CONFIRMING_READS * request_sessions();
    let program = [Instruction::Control(Control::SetOutput {
        line: 2,
        on: true,
    })];
    let (mut c, _) = client(Script::default());
    c.check_status().unwrap();
    c.link_mut().peer.script.garble = Some((REPLY_READ_BACK, lost));
    let r = c.upload_verified(1, &program).unwrap();
    assert_eq!(c.link().peer.script.garble, Some((REPLY_READ_BACK, 0)));
    assert_eq!((r.checked, r.restored), (1, 0));
    let m = &robot(&c).machine;
    assert_eq!(m.program_len(1), 1);
    assert_eq!(m.instruction(1, 1), Some(&program[0]));
}

/// The status read that closes a verified upload only acknowledges errors of refused twins;
/// when noise makes it unreadable (`CONFIRMING_READS` reads, every session garbled) the
/// upload, proven by its read-backs, still succeeds.
#[test]
fn a_verified_upload_is_not_failed_by_noise_on_its_closing_status() {
    let lost = CONFIRMING_READS * request_sessions();
    let program = [
        Instruction::Control(Control::SetOutput { line: 2, on: true }),
        Instruction::Control(Control::End),
    ];
    let (mut c, _) = client(Script::default());
    c.check_status().unwrap();
    c.link_mut().peer.script.garble = Some((REPLY_ENQUIRE, lost));
    let r = c.upload_verified(1, &program).unwrap();
    assert_eq!(c.link().peer.script.garble, Some((REPLY_ENQUIRE, 0)));
    assert_eq!((r.checked, r.restored), (2, 0));
    let m = &robot(&c).machine;
    assert_eq!(m.program_len(1), 2);
    assert_eq!(m.instruction(1, 2), Some(&program[1]));
}

/// A robot that falls silent is reported within one session by the agreeing reads, the verified
/// store and upload and the confirmed command (rule 3: no new session, no further status read),
/// wherever it falls silent: at the first program information or read-back, at the store of a
/// verified store or upload, at the store again after read-backs showed the first one missing
/// (it was swallowed), at the send of a confirmed command (after the status before it),
/// in the closing pass of the upload (after the store's two agreeing read-backs), or at its
/// closing status (after all four).
#[test]
fn a_robot_that_falls_silent_is_reported_within_one_session_by_every_verifying_call() {
    let program = [Instruction::Control(Control::SetOutput {
        line: 2,
        on: true,
    })];
    type Call = fn(&mut TestClient, &[Instruction]) -> Result<(), Error>;
    /// Silent at once, or after this many more replies with this code.
    type After = Option<(u8, u32)>;
    let calls: [(&str, After, Call); 8] = [
        ("program_info", None, |c, _| c.program_info(1).map(|_| ())),
        ("store_verified", None, |c, p| {
            c.store_verified(1, 1, &p[0]).map(|_| ())
        }),
        ("upload_verified at its first store", None, |c, p| {
            c.upload_verified(1, p).map(|_| ())
        }),
        // The first store swallowed: three agreeing read-backs of nothing, then the re-store.
        (
            "store_verified at its re-store",
            Some((REPLY_READ_BACK, 3)),
            |c, p| c.store_verified(1, 1, &p[0]).map(|_| ()),
        ),
        // The status before the command read (two agreeing replies), then silent at its send.
        ("operate at its send", Some((REPLY_ENQUIRE, 2)), |c, _| {
            c.operate().map(|_| ())
        }),
        ("confirm_stored", None, |c, p| {
            c.confirm_stored(1, 1, &p[0]).map(|_| ())
        }),
        ("closing pass", Some((REPLY_READ_BACK, 2)), |c, p| {
            c.upload_verified(1, p).map(|_| ())
        }),
        ("closing status", Some((REPLY_READ_BACK, 4)), |c, p| {
            c.upload_verified(1, p).map(|_| ())
        }),
    ];
    for (name, after, call) in calls {
        let (mut c, clock) = client(Script::default());
        if name == "store_verified at its re-store" {
            c.link_mut().peer.script.swallow = Some((STORE_CONTROL, 1));
        }
        c.check_status().unwrap();
        match after {
            None => c.link_mut().peer.fall_silent = true,
            Some(after) => c.link_mut().peer.script.silent_after_replies = Some(after),
        }
        let e = call(&mut c, &program).unwrap_err();
        assert!(
            matches!(e, Error::Link(LinkError::NoResponse { attempts }) if attempts == N_ENQ),
            "{name}: {e}"
        );
        let silent = clock.now() - c.link().peer.silent_since.unwrap();
        assert!(silent < one_session(), "{name}: {silent:?}");
    }
}

/// An error the robot latched before the STOP and the client has not reported yet (a
/// RUN_PROGRAM sent plainly while the program runs: busy, code 7) does not hold the STOP back.
/// The first STOP is swallowed, so the status does not show it executed; the confirmed STOP
/// still goes out, the robot ends STOPPED having executed one STOP, and the error is reported
/// once, after it, and acknowledged (docs/protocol.md §5: latched until acknowledged).
#[test]
fn an_error_latched_before_a_stop_does_not_hold_back_the_confirmed_stop() {
    let (mut c, _) = running(Script {
        swallow: Some((STOP, 1)),
        ..Script::default()
    });
    c.send(&asea_protocol::Command::RunProgram { program: 1 })
        .unwrap();
    assert_eq!(robot(&c).machine.last_error(), 7);
    let (before, _) = executed(&c);
    let e = c.stop_at_once().unwrap_err();
    assert!(
        matches!(
            e,
            Error::Robot {
                code: 7,
                count: 1,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(c.link().peer.script.swallow, Some((STOP, 0)));
    assert_eq!(robot(&c).machine.status().state, State::Stopped);
    assert_eq!(executed(&c), (before.wrapping_add(1), stop_digest()));
    assert_eq!(robot(&c).machine.last_error(), 0, "acknowledged");
    assert_eq!(c.check_status().unwrap().state, State::Stopped);
}

/// A command the robot acknowledged and did not execute (the line forged the ACK) is proven not
/// executed by the status (the count did not move) and sent again: the call succeeds and the
/// robot has executed it exactly once.
#[test]
fn a_command_acknowledged_and_not_executed_is_sent_again() {
    let (mut c, _) = client(Script {
        swallow: Some((SET_BASE_SPEED, 1)),
        ..Script::default()
    });
    let (before, _) = executed(&c);
    let speed = asea_protocol::Speed::from_value("base", 0.5).unwrap();
    c.set_base_speed(speed).unwrap();
    assert_eq!(c.link().peer.script.swallow, Some((SET_BASE_SPEED, 0)));
    let sent = asea_protocol::Command::SetBaseSpeed(speed).to_frame();
    assert_eq!(
        executed(&c),
        (
            before.wrapping_add(1),
            telegram_digest(SET_BASE_SPEED, &sent.data)
        ),
        "executed once"
    );
}

/// A command with an effect whose place on the line another command took (the count moved by
/// one, with the other telegram's digest) is reported as a foreign delivery, never taken for
/// its own.
#[test]
fn another_command_executed_in_place_of_ours_is_foreign() {
    let other =
        asea_protocol::Command::SetMaxSpeed(asea_protocol::Speed::from_value("max", 1.0).unwrap())
            .encode(&asea_protocol::FrameConfig::default())
            .unwrap();
    let (mut c, _) = client(Script {
        replace: Some((SET_BASE_SPEED, other)),
        ..Script::default()
    });
    let speed = asea_protocol::Speed::from_value("base", 0.5).unwrap();
    let e = c.set_base_speed(speed).unwrap_err();
    assert!(matches!(e, Error::Foreign { executed: 1, .. }), "{e:?}");
}

/// A program-info reply telegram with its own good check value (for the line to forge).
fn program_info_reply(program: u8, count: u16, highest: u16, total: u16) -> Vec<u8> {
    asea_protocol::Reply::ProgramInfo {
        program,
        count,
        highest,
        total,
    }
    .encode(&asea_protocol::FrameConfig::default())
    .unwrap()
}

/// PROGRAM_INFO is taken only from `AGREE_STORED` (2) answers in a row that agree and name the
/// program asked for: a forged first answer is not taken alone, a forged second one does not
/// agree with the first, and two answers about another program are not this program's.
#[test]
fn program_info_is_taken_from_answers_that_agree_and_name_the_program() {
    let (wait, end) = (WAIT_FOR_START, END);
    // Program 1 holds three instructions (highest number 3), program 2 two: five in memory.
    let setup = || {
        let (mut c, _) = client(Script::default());
        c.upload(1, &[wait, wait, end]).unwrap();
        c.upload(2, &[wait, end]).unwrap();
        c
    };
    let truth = (3, 3, 5);
    let forged = program_info_reply(1, 4, 4, 6);
    for skip in [0, 1] {
        let mut c = setup();
        c.link_mut().peer.script.forge_reply = Some((REPLY_PROGRAM_INFO, skip, 1, forged.clone()));
        assert_eq!(
            c.program_info(1).unwrap(),
            truth,
            "answer {} forged",
            skip + 1
        );
        assert_eq!(
            c.link().peer.script.forge_reply.as_ref().map(|f| f.2),
            Some(0)
        );
    }
    let mut c = setup();
    let other = program_info_reply(2, 2, 2, 5);
    c.link_mut().peer.script.forge_reply = Some((REPLY_PROGRAM_INFO, 0, 2, other));
    assert_eq!(c.program_info(1).unwrap(), truth);
    assert_eq!(
        c.link().peer.script.forge_reply.as_ref().map(|f| f.2),
        Some(0)
    );
}

/// A batch upload on a clean line reads every instruction back twice (once in its program's
/// verified upload, once more after the whole batch) and repairs nothing; a program already in
/// memory is replaced, not added to.
#[test]
fn a_clean_batch_upload_reads_every_instruction_back_twice() {
    let (mut c, _) = client(Script::default());
    let (wait, end) = (WAIT_FOR_START, END);
    // Program 2 holds four instructions before the batch, which gives it two.
    c.upload(2, &[wait, wait, wait, end]).unwrap();
    let one = [wait, wait, end];
    let two = [wait, end];
    let r = c.upload_batch(&[(1, &one), (2, &two)]).unwrap();
    assert_eq!(r.checked, 2 * (one.len() + two.len()));
    assert_eq!((r.restored, r.refused_twins), (0, 0));
    assert_eq!(c.program_info(2).unwrap(), (2, 2, 5));
}

/// A read-back reply telegram for `program`, `instruction` showing `stored`, with its own good
/// check value (for the line to forge).
fn read_back_reply(program: u8, instruction: u16, stored: Instruction) -> Vec<u8> {
    asea_protocol::Reply::ReadBack {
        program,
        instruction,
        stored: Some(stored),
    }
    .encode(&asea_protocol::FrameConfig::default())
    .unwrap()
}

/// A read-back reply whose check value is good but which names another slot is not taken for
/// the slot asked for.
#[test]
fn a_read_back_naming_another_slot_is_refused() {
    let (wait, end) = (WAIT_FOR_START, END);
    let other = read_back_reply(1, 2, end);
    let (mut c, _) = client(Script::default());
    c.upload(1, &[wait, end]).unwrap();
    c.link_mut().peer.script.forge_reply = Some((REPLY_READ_BACK, 0, 1, other));
    let e = c.read_back(1, 1).unwrap_err();
    assert!(matches!(e, Error::UnexpectedReply(_)), "{e:?}");
}

/// A store is confirmed by two read-backs in a row that agree, and refuted only by three that
/// agree on something else: one true answer, two forged ones showing another instruction (each
/// agreeing with the one before it only once), then the true one twice: stored.
#[test]
fn only_answers_that_agree_in_a_row_confirm_a_store() {
    let (wait, end) = (WAIT_FOR_START, END);
    let forged = read_back_reply(1, 1, end);
    let (mut c, _) = client(Script::default());
    c.upload(1, &[wait, end]).unwrap();
    c.link_mut().peer.script.forge_reply = Some((REPLY_READ_BACK, 1, 2, forged));
    assert!(c.confirm_stored(1, 1, &wait).unwrap());
    assert_eq!(
        c.link().peer.script.forge_reply.as_ref().map(|f| f.2),
        Some(0)
    );
}

/// A twin of a STORE_CONTROL landing as instruction `instruction` of `program`: the
/// instruction `stored` there.
fn twin_store(program: u8, instruction: u16, stored: Control) -> Frame {
    asea_protocol::Command::StoreControl {
        program,
        instruction,
        control: stored,
    }
    .to_frame()
}

/// A twin that the robot refuses: a STORE_CONTROL whose instruction number was corrupted to 0.
fn refused_twin() -> Frame {
    let mut f = twin_store(1, 9, WAIT_CONTROL);
    f.data[1..3].fill(0);
    f
}

/// `twin` rides on the STORE_CONTROL after the first `skip`.
fn twin_on_store(skip: u32, twin: Frame) -> Twin {
    Twin {
        code: STORE_CONTROL,
        skip,
        count: 1,
        twin,
    }
}

/// A verified upload reads its whole program back once more at the end: a twin of its second
/// store that overwrote its first instruction (already verified) is found there, stored again
/// and counted as restored.
#[test]
fn a_verified_upload_restores_what_a_later_twin_overwrote() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (mut c, _) = client(Script {
        twins: vec![twin_on_store(1, twin_store(1, 1, Control::End))],
        ..Script::default()
    });
    let program = [wait, wait, end];
    let r = c.upload_verified(1, &program).unwrap();
    assert_eq!(c.link().peer.script.twins[0].count, 0, "the twin ran");
    assert_eq!((r.checked, r.restored, r.refused_twins), (3, 1, 0));
    assert_eq!(robot(&c).machine.instruction(1, 1), Some(&wait));
    assert_eq!(robot(&c).machine.program_len(1), 3);
}

/// `verify` reads an uploaded program back and stores again what differs: a plain upload whose
/// second store carried a twin onto the first instruction is put right, one instruction
/// restored of three checked.
#[test]
fn verify_restores_an_instruction_a_twin_overwrote() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (mut c, _) = client(Script {
        twins: vec![twin_on_store(1, twin_store(1, 1, Control::End))],
        ..Script::default()
    });
    let program = [wait, wait, end];
    c.upload(1, &program).unwrap();
    assert_eq!(
        robot(&c).machine.instruction(1, 1),
        Some(&end),
        "the twin landed"
    );
    let r = c.verify(1, &program).unwrap();
    assert_eq!((r.checked, r.restored), (3, 1));
    assert_eq!(robot(&c).machine.instruction(1, 1), Some(&wait));
}

/// A verified store whose read-backs keep differing (every STORE_CONTROL acknowledged by the
/// line and never delivered) fails with `Verify`, naming the slot: the robot gave no reason. When
/// the robot shows a latched error that was already reported (RUN_PROGRAM of a program it does
/// not hold, the acknowledgement of that error lost on the line), the failure names that error
/// again, with the slot, rather than a bare `Verify`.
#[test]
fn a_store_that_never_takes_names_the_robots_latched_error_or_none() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (mut c, _) = client(Script {
        swallow: Some((STORE_CONTROL, u32::MAX)),
        ..Script::default()
    });
    c.check_status().unwrap();
    let e = c.upload_verified(1, &[wait, end]).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Verify {
                program: 1,
                instruction: 1
            }
        ),
        "{e:?}"
    );

    let (mut c, _) = client(Script {
        lose_ack_errors: true,
        ..Script::default()
    });
    c.check_status().unwrap();
    let no_program = asea_protocol::RobotError::NoProgram.code();
    let e = c.run_program(9).unwrap_err();
    assert!(
        matches!(e, Error::Robot { code, .. } if code == no_program),
        "{e:?}"
    );
    assert_eq!(
        robot(&c).machine.status().last_error,
        no_program,
        "still latched"
    );
    c.link_mut().peer.script.swallow = Some((STORE_CONTROL, u32::MAX));
    let e = c.upload_verified(1, &[wait, end]).unwrap_err();
    assert!(
        matches!(
            e,
            Error::Robot {
                code,
                program: 1,
                instruction: 1,
                ..
            } if code == no_program
        ),
        "{e:?}"
    );
}

/// The DELETE_PROGRAM telegrams for `program` the robot executed.
fn deletes(c: &TestClient, program: u8) -> usize {
    robot(c)
        .machine
        .executed
        .iter()
        .filter(|f| f.code == DELETE_PROGRAM && f.data == [program])
        .count()
}

/// The batch clears its programs first, and a program already gone when its DELETE_PROGRAM
/// arrives is what the batch wanted: two program-information answers forged alike (program 1
/// holding two instructions, when the memory is empty) make the batch delete a program the robot
/// does not hold; the robot refuses with "no such program" and the batch goes on. A program the
/// robot refuses to delete because it is running fails the batch with the robot's reason, and
/// nothing is stored.
#[test]
fn the_batch_deletes_its_programs_and_only_a_missing_program_is_no_error() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (mut c, _) = client(Script {
        forge_reply: Some((REPLY_PROGRAM_INFO, 0, 2, program_info_reply(1, 2, 2, 2))),
        ..Script::default()
    });
    let one = [wait, end];
    c.upload_batch(&[(1, &one)]).unwrap();
    assert_eq!(
        c.link().peer.script.forge_reply.as_ref().map(|f| f.2),
        Some(0)
    );
    assert_eq!(deletes(&c, 1), 1);
    assert_eq!(c.program_info(1).unwrap(), (2, 2, 2));

    // Program 1 runs (it holds a wait for the start and its end) and the batch would give it
    // three instructions: only the refused DELETE is executed.
    let (mut c, _) = running(Script::default());
    let before = robot(&c).machine.status().executed;
    let three = [wait, wait, end];
    let e = c.upload_batch(&[(1, &three)]).unwrap_err();
    assert!(
        matches!(e, Error::Robot { code, .. } if code == asea_protocol::RobotError::Busy.code()),
        "{e:?}"
    );
    assert_eq!(robot(&c).machine.status().executed, before.wrapping_add(1));
    assert_eq!(deletes(&c, 1), 1);
    assert_eq!(c.program_info(1).unwrap(), (2, 2, 2));
}

/// The batch's own uploads repair what they see and the batch's second read-back repairs what a
/// later program's twin did to an earlier one: a store of program 1 acknowledged and not
/// executed (stored again), a twin refused (instruction number corrupted to 0: counted), and a
/// twin of program 2's first store landing on program 1's first instruction (program number
/// corrupted), put right when the batch reads program 1 back once more. Nothing is uploaded
/// again: no slot was added.
#[test]
fn a_twin_over_an_earlier_program_of_the_batch_is_put_right_by_its_second_read_back() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (Instruction::Control(WAIT_CONTROL), Instruction::Control(Control::End)) = (wait, end)
    else {
        unreachable!()
    };
    let (mut c, _) = client(Script {
        // STORE_CONTROLs: 1 (1,1) swallowed, 2 (1,1) again, 3 (1,2) with the refused twin,
        // 4 (1,3), 5 (2,1) with its twin on (1,1), 6 (2,2).
        swallow: Some((STORE_CONTROL, 1)),
        twins: vec![
            twin_on_store(2, refused_twin()),
            twin_on_store(4, twin_store(1, 1, Control::End)),
        ],
        ..Script::default()
    });
    let one = [wait, wait, end];
    let two = [wait, end];
    let r = c.upload_batch(&[(1, &one), (2, &two)]).unwrap();
    assert_eq!(
        (r.checked, r.restored, r.refused_twins),
        (2 * (one.len() + two.len()), 2, 1)
    );
    assert_eq!(deletes(&c, 1), 0);
    assert_eq!(robot(&c).machine.instruction(1, 1), Some(&wait));
    assert_eq!(c.program_info(1).unwrap(), (3, 3, 5));
}

/// A twin that lands beyond a program's end passes every read-back of the program's
/// instructions; the batch upload finds it in the program information (4 instructions, the
/// highest 9, for 3 written), deletes the program and uploads it once more. That second upload
/// meets a store acknowledged and not executed (stored again: restored 1) and a twin the robot
/// refused (instruction number corrupted to 0: its error latched, acknowledged and counted), and
/// the report counts its read-backs with the batch's: 2 × 5 for the batch, 3 for the second
/// upload.
#[test]
fn a_twin_beyond_a_programs_end_is_cleared_by_uploading_the_program_again() {
    let (wait, end) = (WAIT_FOR_START, END);
    let (mut c, _) = client(Script {
        // STORE_CONTROLs 1–5 are the batch's (the twin rides on 2), 6 the second upload's first
        // (swallowed), 7 the same store again, 8 its second instruction (with the refused twin).
        twins: vec![
            twin_on_store(1, twin_store(1, 9, WAIT_CONTROL)),
            twin_on_store(7, refused_twin()),
        ],
        swallow: Some((STORE_CONTROL, 1)),
        swallow_skip: 5,
        ..Script::default()
    });
    let one = [wait, wait, end];
    let two = [wait, end];
    let r = c.upload_batch(&[(1, &one), (2, &two)]).unwrap();
    assert_eq!(
        (r.checked, r.restored, r.refused_twins),
        (2 * (one.len() + two.len()) + one.len(), 1, 1)
    );
    assert_eq!(
        deletes(&c, 1),
        1,
        "program 1 deleted once, for its second upload"
    );
    assert_eq!(deletes(&c, 2), 0);
    assert_eq!(c.program_info(1).unwrap(), (3, 3, 5));
    assert_eq!(
        robot(&c).machine.last_error(),
        0,
        "the refused twin's error acknowledged"
    );
    let script = &c.link().peer.script;
    assert!(
        script.twins.iter().all(|t| t.count == 0),
        "both twins landed"
    );
    assert_eq!(script.swallow, Some((STORE_CONTROL, 0)));
}

/// A twin that lands beyond the program's end at every upload: the batch deletes and uploads
/// the program `program_uploads` times in all, then reports the extra slot, never a success.
#[test]
fn a_program_that_keeps_an_extra_slot_is_reported_after_its_uploads() {
    let (wait, end) = (WAIT_FOR_START, END);
    let uploads = ClientConfig::default().retry.program_uploads;
    let one = [wait, wait, end];
    let (mut c, _) = client(Script {
        // The twin rides on the second store of every upload of program 1: 1 + 3k stores
        // before the one of upload k.
        twins: (0..uploads)
            .map(|k| twin_on_store(1 + 3 * k, twin_store(1, 9, WAIT_CONTROL)))
            .collect(),
        ..Script::default()
    });
    let e = c.upload_batch(&[(1, &one)]).unwrap_err();
    assert!(
        matches!(
            e,
            Error::ExtraSlots {
                program: 1,
                count: 4,
                expected: 3
            }
        ),
        "{e:?}"
    );
    assert_eq!(deletes(&c, 1), usize::try_from(uploads).unwrap() - 1);
}
