//! `--foxglove [HOST:]PORT` on `mrtwin node` and `mrtwin demo`: the twin's live view, a
//! Foxglove WebSocket server ([`bridge::foxglove`]) attached to the node as a watcher.
//! Off unless asked for; a bare port listens on loopback.

use anyhow::{bail, Context, Result};
use node::runner::TwinNode;

/// `PORT`, `HOST:PORT` or `[V6]:PORT` → (host, port); a bare port is `127.0.0.1`.
pub fn parse_listen(spec: &str) -> Result<(String, u16)> {
    let spec = spec.trim();
    let (host, port) = match spec.rsplit_once(':') {
        None => ("127.0.0.1", spec),
        Some((h, p)) => (h.trim_start_matches('[').trim_end_matches(']'), p),
    };
    let port: u16 = port.parse().with_context(|| {
        format!("--foxglove '{spec}': expected PORT or HOST:PORT (e.g. 8765 or 127.0.0.1:8765)")
    })?;
    if host.is_empty() {
        bail!("--foxglove '{spec}': the host is empty (give PORT alone for loopback)");
    }
    Ok((host.to_string(), port))
}

/// Start the live view of `node` (fully qualified name `node_fqn`) on `spec`, print how to
/// open it, and return the port it listens on.
#[cfg(feature = "foxglove")]
pub fn attach(node: &mut TwinNode, spec: &str, node_fqn: &str) -> Result<u16> {
    let (host, port) = parse_listen(spec)?;
    let (namespace, _) = node::transports::split_name(node_fqn);
    let server = bridge::foxglove::FoxgloveServer::start(&bridge::foxglove::FoxgloveConfig {
        host: host.clone(),
        port,
        namespace: namespace.to_string(),
        name: format!("mrtwin {node_fqn}"),
    })
    .context("start the Foxglove live view")?;
    let port = server.port();
    let url_host = if host.contains(':') {
        format!("[{host}]")
    } else {
        host
    };
    println!(
        "Foxglove live view: ws://{url_host}:{port} (Foxglove → Open connection → Foxglove WebSocket; \
         F–v loop: Plot panel, X axis {}.velocity_m_s)",
        bridge::foxglove::channel_name(namespace, bridge::foxglove::FV_LOOP)
    );
    node.attach_viewer(Box::new(server));
    Ok(port)
}

/// Without the `foxglove` feature: an error that names it.
#[cfg(not(feature = "foxglove"))]
pub fn attach(_node: &mut TwinNode, spec: &str, _node_fqn: &str) -> Result<u16> {
    parse_listen(spec)?;
    bail!(
        "--foxglove: the Foxglove live view is not compiled into this build; rebuild with the \
         cargo feature `foxglove` (cargo build --release -p mrtwin --features foxglove)"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listen_specs() {
        assert_eq!(parse_listen("8765").unwrap(), ("127.0.0.1".into(), 8765));
        assert_eq!(parse_listen("0.0.0.0:0").unwrap(), ("0.0.0.0".into(), 0));
        assert_eq!(parse_listen("[::1]:9000").unwrap(), ("::1".into(), 9000));
        let e = parse_listen("localhost:http").unwrap_err().to_string();
        assert!(
            e.contains("'localhost:http'") && e.contains("HOST:PORT"),
            "{e}"
        );
        assert!(parse_listen(":8765").is_err());
        assert!(parse_listen("70000").is_err());
    }
}
