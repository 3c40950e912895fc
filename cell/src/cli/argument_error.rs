//! Argument errors as one line: the parser's error kinds rendered in windcell's own words (the
//! parser's own rendering spans 3–7 lines with a usage block and tips), exit code 2.

use clap::error::{ContextKind, ContextValue, ErrorKind};

fn context(error: &clap::Error, kind: ContextKind) -> Option<String> {
    match error.get(kind)? {
        ContextValue::String(s) => Some(s.clone()),
        ContextValue::Strings(v) => Some(v.join(", ")),
        ContextValue::StyledStr(s) => Some(s.to_string()),
        ContextValue::StyledStrs(v) => Some(
            v.iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", "),
        ),
        ContextValue::Number(n) => Some(n.to_string()),
        ContextValue::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

/// `windcell plan` (or `windcell lathe plan`, as deep as the command line names subcommands)
/// when the command line names a subcommand, else `windcell`.
fn command(args: &[String]) -> String {
    use clap::CommandFactory;
    let cli = crate::cli::Cli::command();
    let mut name = "windcell".to_string();
    let mut at = &cli;
    for arg in args.iter().skip(1) {
        match at.find_subcommand(arg) {
            Some(sub) => {
                name = format!("{name} {arg}");
                at = sub;
            }
            None => break,
        }
    }
    name
}

/// The one-line message for a parser error (without the `windcell: ` prefix); `args` is the
/// command line it came from.
pub fn render(error: &clap::Error, args: &[String]) -> String {
    let arg = context(error, ContextKind::InvalidArg).unwrap_or_default();
    let value = context(error, ContextKind::InvalidValue).unwrap_or_default();
    let help = format!("see `{} --help`", command(args));
    let suggestion = context(error, ContextKind::SuggestedArg)
        .or_else(|| context(error, ContextKind::SuggestedSubcommand))
        .or_else(|| context(error, ContextKind::SuggestedValue))
        .map(|s| format!("did you mean `{s}`? "))
        .unwrap_or_default();
    let message = match error.kind() {
        ErrorKind::InvalidValue if value.is_empty() => format!("{arg} needs a value"),
        ErrorKind::InvalidValue => {
            let valid = context(error, ContextKind::ValidValue)
                .map(|v| format!(" (one of: {v})"))
                .unwrap_or_default();
            format!("`{value}` is not a valid value for {arg}{valid}")
        }
        ErrorKind::UnknownArgument => format!("unknown argument `{arg}`"),
        ErrorKind::InvalidSubcommand => format!(
            "unknown command `{}`",
            context(error, ContextKind::InvalidSubcommand).unwrap_or_default()
        ),
        ErrorKind::NoEquals => format!("{arg} needs `=` before its value"),
        ErrorKind::ValueValidation => {
            let reason = std::error::Error::source(error)
                .map(ToString::to_string)
                .unwrap_or_else(|| "not accepted".to_string());
            format!("`{value}` is not a valid value for {arg}: {reason}")
        }
        ErrorKind::TooManyValues => format!("{arg}: one value too many (`{value}`)"),
        ErrorKind::TooFewValues | ErrorKind::WrongNumberOfValues => {
            let expected = context(error, ContextKind::ExpectedNumValues).unwrap_or_default();
            let actual = context(error, ContextKind::ActualNumValues).unwrap_or_default();
            format!("{arg} takes {expected} values, {actual} given")
        }
        ErrorKind::ArgumentConflict => {
            let prior = context(error, ContextKind::PriorArg).unwrap_or_default();
            format!("{arg} cannot be used with {prior}")
        }
        ErrorKind::MissingRequiredArgument => format!("missing required argument {arg}"),
        ErrorKind::MissingSubcommand | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            "a command is needed (plan, geodesic, sweep, triasym, sim-robot, sim-indexer)"
                .to_string()
        }
        _ => error
            .to_string()
            .lines()
            .map(|l| l.trim().trim_start_matches("error:").trim())
            .find(|l| !l.is_empty())
            .unwrap_or("invalid arguments")
            .to_string(),
    };
    format!("{message}; {suggestion}{help}")
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::Cli;

    fn rendered(args: &[&str]) -> String {
        let error = Cli::try_parse_from(args).unwrap_err();
        let args: Vec<String> = args.iter().map(ToString::to_string).collect();
        render(&error, &args)
    }

    #[test]
    fn each_kind_is_one_line_naming_the_argument() {
        let cases: [(&[&str], &str); 7] = [
            (
                &["windcell", "sweep", "j.toml", "-o", "d", "--paths", "0"],
                "`0` is not a valid value for --paths <PATHS>: 0 is not in 1..=255; see `windcell sweep --help`",
            ),
            (
                &["windcell", "sim-robot", "--checksum", "md5"],
                "`md5` is not a valid value for --checksum <CHECKSUM> (one of: sum8, crc16); see `windcell sim-robot --help`",
            ),
            (
                &["windcell", "plan", "j.toml"],
                "missing required argument --out <DIR>; see `windcell plan --help`",
            ),
            (
                &["windcell", "plan", "j.toml", "-o", "d", "--jsn"],
                "unknown argument `--jsn`; did you mean `--json`? see `windcell plan --help`",
            ),
            (
                &["windcell", "pln"],
                "unknown command `pln`; did you mean `plan`? see `windcell --help`",
            ),
            (
                &["windcell"],
                "a command is needed (plan, geodesic, sweep, triasym, sim-robot, sim-indexer); see `windcell --help`",
            ),
            (
                &[
                    "windcell",
                    "geodesic",
                    "m.stl",
                    "--start",
                    "NaN,0,10",
                    "--heading",
                    "0",
                ],
                "`NaN,0,10` is not a valid value for --start <START>: `NaN` is not finite; see `windcell geodesic --help`",
            ),
        ];
        for (args, expected) in cases {
            assert_eq!(rendered(args), expected, "{args:?}");
        }
    }

    #[test]
    fn negative_numbers_are_values() {
        let cli = Cli::try_parse_from([
            "windcell",
            "geodesic",
            "m.stl",
            "--start",
            "-1,0,10",
            "--heading",
            "-45",
            "--length",
            "-5",
            "--lambda",
            "-0.1",
            "--mu",
            "-1",
        ]);
        assert!(cli.is_ok(), "{}", cli.map(|_| ()).unwrap_err());
    }

    /// The kinds windcell's own options cannot raise today (they take no `=`-only values, no
    /// counted value lists, no conflicting flags), built by hand with each kind of context value,
    /// so a new option that raises them still gets its one line.
    #[test]
    fn kinds_built_by_hand_render_their_context() {
        use clap::builder::StyledStr;
        let plan = ["windcell".to_string(), "plan".to_string()];
        let built = |kind: ErrorKind, context: Vec<(ContextKind, ContextValue)>| {
            let mut error = clap::Error::new(kind);
            for (k, v) in context {
                error.insert(k, v);
            }
            render(&error, &plan)
        };
        let styled = |s: &str| ContextValue::StyledStr(StyledStr::from(s.to_string()));
        assert_eq!(
            built(
                ErrorKind::NoEquals,
                vec![(ContextKind::InvalidArg, styled("--out"))]
            ),
            "--out needs `=` before its value; see `windcell plan --help`"
        );
        assert_eq!(
            built(
                ErrorKind::TooManyValues,
                vec![
                    (
                        ContextKind::InvalidArg,
                        ContextValue::String("--start".into())
                    ),
                    (ContextKind::InvalidValue, ContextValue::String("4".into())),
                ]
            ),
            "--start: one value too many (`4`); see `windcell plan --help`"
        );
        for kind in [ErrorKind::TooFewValues, ErrorKind::WrongNumberOfValues] {
            assert_eq!(
                built(
                    kind,
                    vec![
                        (
                            ContextKind::InvalidArg,
                            ContextValue::String("--start".into())
                        ),
                        (ContextKind::ExpectedNumValues, ContextValue::Number(3)),
                        (ContextKind::ActualNumValues, ContextValue::Number(2)),
                    ]
                ),
                "--start takes 3 values, 2 given; see `windcell plan --help`"
            );
        }
        assert_eq!(
            built(
                ErrorKind::ArgumentConflict,
                vec![
                    (ContextKind::InvalidArg, styled("--json")),
                    (
                        ContextKind::PriorArg,
                        ContextValue::StyledStrs(vec![
                            StyledStr::from("--svg"),
                            StyledStr::from("--record"),
                        ])
                    ),
                ]
            ),
            "--json cannot be used with --svg, --record; see `windcell plan --help`"
        );
        assert_eq!(
            built(
                ErrorKind::UnknownArgument,
                vec![(ContextKind::InvalidArg, ContextValue::Bool(true))]
            ),
            "unknown argument `true`; see `windcell plan --help`"
        );
        // Any other kind: the parser's first line that says something.
        let raw = clap::Error::raw(ErrorKind::Io, "the terminal went away\nsecond line\n");
        assert_eq!(
            render(&raw, &plan),
            "the terminal went away; see `windcell plan --help`"
        );
    }

    #[test]
    fn an_option_without_its_value_says_so() {
        assert_eq!(
            rendered(&["windcell", "sim-robot", "--checksum"]),
            "--checksum <CHECKSUM> needs a value; see `windcell sim-robot --help`"
        );
    }
}
