//! `tetloc view`: the volume renderer in a browser, rendered on the machine that holds the
//! mesh and the GPU, as ParaViewWeb and trame do, but made not to lag.
//!
//! Threads, on std alone (a few long-lived connections need no async runtime, and
//! axum/tokio would about double this binary's build on a 2-core machine; `tungstenite`
//! speaks WebSocket over a plain `TcpStream`):
//! - the accept loop ([`http`]): a thread per connection; the token is checked before
//!   anything else, and the server answers only its page, its frames and its WebSocket;
//! - the render thread ([`scene`]): owns the locator and the marcher, renders the newest view
//!   state: small frames while the view moves (their size adapts to the frame time), a
//!   full-size frame once it stops;
//! - the encode thread ([`frames`]): JPEG while the view moves, PNG (lossless) when it is
//!   still, so frame N+1 is rendered while frame N is encoded and sent. Each stage keeps only
//!   the newest frame: the latest frame wins, and none is queued;
//! - a thread per WebSocket client ([`client`]): input in, the newest frame out once the
//!   client has acknowledged enough of the frames it was sent.

pub mod bench;
mod client;
mod frames;
mod http;
mod scene;

use crate::backend::BackendOptions;
use crate::mesh_arg;
use anyhow::{Context, Result};
use std::ffi::OsString;
use std::net::TcpListener;
use std::path::PathBuf;
use std::sync::Arc;
use tetloc_render as tr;

#[derive(clap::Args)]
pub struct ViewArgs {
    /// A mesh file, or SHAPE:N to generate one.
    mesh: OsString,
    /// The field shown first (default: the state's, else the mesh's first scalar).
    #[arg(long)]
    field: Option<String>,
    /// TCP port (0: any free port).
    #[arg(long, default_value_t = 8765)]
    port: u16,
    /// Address to listen on. Anything but the loopback exposes the viewer (with its token) to
    /// the network: prefer `ssh -L` to reach a remote machine.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// The token every request must carry (default: a random one, printed in the URL).
    #[arg(long)]
    token: Option<String>,
    /// cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, auto.
    #[arg(long, default_value = "auto")]
    backend: String,
    /// Vulkan device index (see `tetloc devices`).
    #[arg(long)]
    device: Option<usize>,
    /// soft-bvh layout: fast, compact (40 % less GPU memory) or small (see `tetloc locate --help`).
    #[arg(long, default_value = "fast", value_parser = clap::builder::PossibleValuesParser::new(tetloc_vulkan::PRESETS))]
    preset: String,
    /// Size WIDTHxHEIGHT of a still frame [default: 768x768, or the state's].
    #[arg(long)]
    size: Option<String>,
    /// A view state (JSON) exported by the viewer, to start from.
    #[arg(long)]
    state: Option<PathBuf>,
    /// A time series (an Exodus file with steps, a .pvd, a Gmsh file of several steps): start
    /// at time step K (0-based; default: the state's, else the first). The page's time slider
    /// moves through the steps.
    #[arg(long, value_name = "K")]
    time_step: Option<usize>,
    #[command(flatten)]
    source: mesh_arg::MeshOptions,
    /// Print only the URL, errors and warnings.
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: ViewArgs) -> Result<()> {
    let state = a.state.as_deref().map(crate::render::load_state).transpose()?;
    let token = match &a.token {
        Some(t) => check_token(t)?,
        None => random_token()?,
    };
    // Bind before the (long) mesh load, so a port in use fails at once.
    let listener =
        TcpListener::bind((a.host.as_str(), a.port)).with_context(|| format!("listening on {}:{}", a.host, a.port))?;
    let addr = listener.local_addr()?;
    if !addr.ip().is_loopback() {
        eprintln!(
            "warning: --host {}: the viewer is reachable from other machines by anyone who has the token; prefer the default 127.0.0.1 and `ssh -L`",
            a.host
        );
    }
    let step = a.time_step.or(state.as_ref().and_then(|s| s.time_step));
    let (mut mesh, series) = crate::time_steps::load_series(&a.mesh, a.source.format.as_deref(), a.source.seed, step)?;
    if let Some(m) = Arc::get_mut(&mut mesh) {
        tr::state::add_magnitudes(m);
    }
    let field = a.field.clone().or_else(|| state.as_ref().map(|s| s.field.clone()));
    let field = crate::render::field_or_first(field.as_deref(), &mesh)?;
    tetloc_core::ops::fields::resolve_scalar(&mesh.fields, &field).context("--field")?;
    let mut state = match state {
        Some(s) => s,
        None => tr::ViewState::new(&mesh, &field, 768, 768),
    };
    state.field = field;
    state.time_step = step;
    if let Some(size) = &a.size {
        let (w, h) = tr::parse_size(size)?;
        state.size = [w, h];
    }
    state.validate()?;
    scene::check_size(state.size).map_err(anyhow::Error::msg)?;
    let opts = BackendOptions { device: a.device, quiet: a.quiet, preset: a.preset.clone(), ..Default::default() };
    let hub = Arc::new(frames::Hub::new(token.clone(), state.clone()));
    let times = series.as_ref().map_or_else(Vec::new, |s| s.times().to_vec());
    let backend = scene::spawn(mesh.clone(), series, &a.backend, opts, state.clone(), hub.clone())?;
    hub.set_describe(scene::describe(&mesh, &times, &state, &backend));
    frames::spawn_encoder(hub.clone());
    // Ctrl-C ends a server normally.
    crate::signals::exit_zero_on_interrupt();
    let host = if addr.is_ipv6() { format!("[{}]", addr.ip()) } else { addr.ip().to_string() };
    println!("http://{host}:{}/?token={token}", addr.port());
    use std::io::Write;
    std::io::stdout().flush().ok();
    http::serve(listener, hub);
    Ok(())
}

/// A token from the command line: printable ASCII without spaces or URL specials, so it
/// travels in a URL as it is.
fn check_token(t: &str) -> Result<String> {
    let ok = (8..=128).contains(&t.len()) && t.bytes().all(|b| b.is_ascii_alphanumeric() || b"-_.~".contains(&b));
    if !ok {
        anyhow::bail!("--token: 8 to 128 characters of A-Z, a-z, 0-9, '-', '_', '.', '~'");
    }
    Ok(t.to_string())
}

/// 128 random bits from the system, as 32 hex digits.
fn random_token() -> Result<String> {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .context("reading /dev/urandom for a token")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens() {
        let a = random_token().unwrap();
        assert_eq!(a.len(), 32);
        assert_ne!(a, random_token().unwrap());
        assert!(check_token(&a).is_ok());
        assert!(check_token("short").is_err());
        assert!(check_token("has space in it").is_err());
        assert!(check_token("a&b=cdefgh").is_err());
    }
}
