//! What the commands and nodes that take a model share on their command line: the model's
//! parameter file (`--params`, [`ParamsArgs`]) and the initial state (`--x0`, [`parse_x0`]).

use crate::{ConfigError, Params};
use std::path::PathBuf;

/// The `--params` flag: the model's parameter file, declared once for every command and node
/// (flatten it with `#[command(flatten)]`).
#[derive(Debug, Clone, Default, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct ParamsArgs {
    /// Physical parameters, a TOML file (m_f, m_l, l, f, g, and the hardware keys l_c, i_l,
    /// j_m, n_g, b_v, tau_c of docs/model.md; missing entries keep the paper's values)
    /// [default: the paper's]
    #[cfg_attr(feature = "clap", arg(long, value_name = "FILE.toml"))]
    pub params: Option<PathBuf>,
}

impl ParamsArgs {
    /// The parameters of the file, if one is given (read and validated).
    pub fn load(&self) -> Result<Option<Params>, ConfigError> {
        self.params
            .as_deref()
            .map(Params::from_toml_file)
            .transpose()
    }

    /// The parameters of the file, or the paper's.
    pub fn params(&self) -> Result<Params, ConfigError> {
        Ok(self.load()?.unwrap_or_default())
    }
}

/// The names of the components of `x0`, with their units.
const X0: [(&str, &str); 4] = [
    ("alpha", "rad"),
    ("beta", "rad"),
    ("alpha_dot", "rad/s"),
    ("beta_dot", "rad/s"),
];

/// Parses an initial state `alpha,beta,alpha_dot,beta_dot` (rad, rad, rad/s, rad/s): four
/// comma-separated finite numbers. The error names the component (`x0[1]`, beta) and the
/// allowed range.
pub fn parse_x0(s: &str) -> Result<[f64; 4], String> {
    let bad = || {
        format!(
            "invalid x0 `{s}`: must be four comma-separated finite numbers \
             alpha,beta,alpha_dot,beta_dot (rad, rad, rad/s, rad/s)"
        )
    };
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let x: [f64; 4] = v.try_into().map_err(|_| bad())?;
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        let (name, unit) = X0[i];
        return Err(format!(
            "invalid `x0[{i}]` ({name}) = {} in `{s}`: must be finite ({unit})",
            x[i]
        ));
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn x0_parser() {
        assert_eq!(parse_x0("0, 1.5,-2,3e-1").unwrap(), [0.0, 1.5, -2.0, 0.3]);
        for (s, part) in [
            ("0,1,2", "four"),
            ("0,1,2,x", "four"),
            ("0,1,2,3,4", "four"),
            ("0,nan,0,0", "`x0[1]` (beta)"),
            ("0,0,0,-inf", "`x0[3]` (beta_dot)"),
        ] {
            let e = parse_x0(s).unwrap_err();
            assert!(e.contains(part) && e.contains(s), "{s}: {e}");
        }
    }

    #[test]
    fn no_file_is_the_paper() {
        let a = ParamsArgs::default();
        assert_eq!(a.params().unwrap(), Params::default());
        let bad = ParamsArgs {
            params: Some("/nonexistent/params.toml".into()),
        };
        assert!(bad.params().is_err());
    }
}
