//! One file per subcommand.

pub mod calibrate;
pub mod diagnose;
pub mod info;
pub mod monte_carlo;
pub mod ports;
pub mod run;
pub mod sim;
pub mod validate;

use tracing_subscriber::EnvFilter;

/// The terminal log layer: warnings and errors by default, more with `-v`; `RUST_LOG` wins.
pub fn console_layer(
    verbose: u8,
) -> Box<dyn tracing_subscriber::Layer<tracing_subscriber::Registry> + Send + Sync> {
    use tracing_subscriber::Layer;
    let default = match verbose {
        0 => "warn",
        1 => "info,bench=debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    tracing_subscriber::fmt::layer().with_writer(std::io::stderr).with_filter(filter).boxed()
}
