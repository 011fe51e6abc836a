//! The handshake front: the address a viewer connects to, in front of the SDK's server, so that
//! viewers offering only the protocol's old name `foxglove.websocket.v1` (Foxglove Studio 1.48,
//! Lichtblick up to 1.22.0, `@foxglove/ws-protocol`'s default) connect too.
//!
//! The SDK's server (0.30) accepts only `foxglove.sdk.v1` (the same protocol under a new name)
//! and `foxglove.sdk.v1.1`, and answers anything else with HTTP 400; it has no setting for
//! another name. The front reads a connection's HTTP upgrade request; when the client offers the
//! old name and neither of the SDK's, it offers `foxglove.sdk.v1` in its place to the SDK's
//! server (on a loopback port of its own) and names the old one back in the server's answer.
//! Every other request passes unchanged. After the handshake it copies bytes both ways.

use std::io;
use std::net::SocketAddr;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::task::JoinSet;

/// The protocol's old name, which the SDK refuses.
pub const OLD_NAME: &str = "foxglove.websocket.v1";
/// The SDK's name of the same protocol.
pub const SDK_V1: &str = "foxglove.sdk.v1";
/// The SDK's newer protocol (a schema table in place of inline schemas).
pub const SDK_V1_1: &str = "foxglove.sdk.v1.1";

/// Longest HTTP head read (bytes): a browser's upgrade request is well under 2 KiB.
const MAX_HEAD: usize = 16 * 1024;
/// Longest wait for a client's request head.
const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

const HEADER: &str = "sec-websocket-protocol";

/// The header lines of an HTTP head (after the request or status line), with their values.
fn protocol_lines(head: &str) -> impl Iterator<Item = (usize, &str)> {
    head.split("\r\n")
        .enumerate()
        .skip(1)
        .filter_map(|(i, line)| {
            let (name, value) = line.split_once(':')?;
            name.trim()
                .eq_ignore_ascii_case(HEADER)
                .then_some((i, value.trim()))
        })
}

/// The request head to hand the SDK's server: `Some` with the offer replaced by
/// `foxglove.sdk.v1` when the client offers [`OLD_NAME`] and none of the SDK's names, `None` to
/// pass it unchanged.
pub fn rewrite_request(head: &str) -> Option<String> {
    let offered: Vec<&str> = protocol_lines(head)
        .flat_map(|(_, v)| v.split(','))
        .map(str::trim)
        .collect();
    let sdk = offered.iter().any(|p| *p == SDK_V1 || *p == SDK_V1_1);
    if sdk || !offered.contains(&OLD_NAME) {
        return None;
    }
    let drop: Vec<usize> = protocol_lines(head).map(|(i, _)| i).collect();
    let mut lines: Vec<String> = head
        .split("\r\n")
        .enumerate()
        .filter(|(i, _)| !drop.contains(i))
        .map(|(_, l)| l.to_owned())
        .collect();
    lines.insert(1, format!("Sec-WebSocket-Protocol: {SDK_V1}"));
    Some(lines.join("\r\n"))
}

/// The server's answer to a renamed request, for the client: `foxglove.sdk.v1` named
/// [`OLD_NAME`], the name the client offered.
pub fn rewrite_response(head: &str) -> String {
    let renamed: Vec<usize> = protocol_lines(head)
        .filter(|(_, v)| *v == SDK_V1)
        .map(|(i, _)| i)
        .collect();
    head.split("\r\n")
        .enumerate()
        .map(|(i, l)| {
            if renamed.contains(&i) {
                format!("Sec-WebSocket-Protocol: {OLD_NAME}")
            } else {
                l.to_owned()
            }
        })
        .collect::<Vec<_>>()
        .join("\r\n")
}

/// Reads an HTTP head (through its blank line) and whatever followed it in the same reads.
async fn read_head(s: &mut TcpStream) -> io::Result<(String, Vec<u8>)> {
    let mut buf = Vec::with_capacity(2048);
    let mut chunk = [0u8; 2048];
    loop {
        let n = s.read(&mut chunk).await?;
        if n == 0 {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "closed in the HTTP head",
            ));
        }
        buf.extend_from_slice(&chunk[..n]);
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let rest = buf.split_off(end + 4);
            let head = String::from_utf8(buf)
                .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "HTTP head not UTF-8"))?;
            return Ok((head, rest));
        }
        if buf.len() > MAX_HEAD {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                "HTTP head too long",
            ));
        }
    }
}

/// One viewer's connection: the handshake (renamed if needed), then bytes both ways.
async fn relay(mut client: TcpStream, backend: SocketAddr) -> io::Result<()> {
    client.set_nodelay(true)?;
    let (head, rest) = tokio::time::timeout(HEAD_TIMEOUT, read_head(&mut client))
        .await
        .map_err(|_| io::Error::new(io::ErrorKind::TimedOut, "no HTTP head"))??;
    let renamed = rewrite_request(&head);
    let mut server = TcpStream::connect(backend).await?;
    server.set_nodelay(true)?;
    server
        .write_all(renamed.as_deref().unwrap_or(head.as_str()).as_bytes())
        .await?;
    server.write_all(&rest).await?;
    if renamed.is_some() {
        let (answer, rest) = read_head(&mut server).await?;
        client
            .write_all(rewrite_response(&answer).as_bytes())
            .await?;
        client.write_all(&rest).await?;
    }
    tokio::io::copy_bidirectional(&mut client, &mut server).await?;
    Ok(())
}

/// A running front: stops accepting, and drops its connections, when dropped.
pub struct Front {
    addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
}

impl Front {
    /// Relays the connections `listener` accepts (bound with `TcpListener::bind`: its errors are
    /// the caller's to report) to the SDK's server at `backend`. Call within a tokio runtime.
    pub fn serve(listener: TcpListener, backend: SocketAddr) -> io::Result<Self> {
        let addr = listener.local_addr()?;
        let task = tokio::spawn(async move {
            let mut relays = JoinSet::new();
            loop {
                tokio::select! {
                    accepted = listener.accept() => match accepted {
                        Ok((conn, _)) => {
                            relays.spawn(async move {
                                if let Err(e) = relay(conn, backend).await {
                                    tracing::debug!("foxglove: a connection ended: {e}");
                                }
                            });
                        }
                        Err(e) => {
                            tracing::warn!("foxglove: accept failed: {e}");
                            tokio::time::sleep(Duration::from_millis(50)).await;
                        }
                    },
                    Some(_) = relays.join_next(), if !relays.is_empty() => {}
                }
            }
        });
        Ok(Self { addr, task })
    }

    /// The address bound (with its port).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for Front {
    fn drop(&mut self) {
        self.task.abort();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(protocols: &[&str]) -> String {
        let mut h = "GET / HTTP/1.1\r\nHost: 127.0.0.1:8765\r\nUpgrade: websocket\r\n".to_owned();
        for p in protocols {
            h.push_str(&format!("Sec-WebSocket-Protocol: {p}\r\n"));
        }
        h + "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n"
    }

    /// Only an offer of the old name without the SDK's is renamed; every other header stays.
    #[test]
    fn only_the_old_name_alone_is_renamed() {
        let old = rewrite_request(&request(&[OLD_NAME])).expect("renamed");
        assert!(
            old.contains("Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n"),
            "{old}"
        );
        assert!(!old.contains(OLD_NAME), "{old}");
        assert!(old.ends_with("Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n"));
        assert!(old.starts_with("GET / HTTP/1.1\r\n"));
        // Two header lines, lower-case name, spaces: one offer.
        let two = request(&["x.other", OLD_NAME])
            .replace("Sec-WebSocket-Protocol", "sec-websocket-protocol");
        let renamed = rewrite_request(&two).expect("renamed");
        assert_eq!(renamed.matches("foxglove.sdk.v1").count(), 1, "{renamed}");
        assert!(!renamed.contains("x.other"), "{renamed}");
        for offer in [
            vec![SDK_V1],
            vec![SDK_V1_1],
            vec![&format!("{OLD_NAME}, {SDK_V1}")],
            vec![OLD_NAME, SDK_V1_1],
            vec!["foxglove.websocket.v2"],
            vec![],
        ] {
            assert_eq!(rewrite_request(&request(&offer)), None, "{offer:?}");
        }
    }

    #[test]
    fn the_answer_names_the_old_name_back() {
        let answer = "HTTP/1.1 101 Switching Protocols\r\nconnection: Upgrade\r\nsec-websocket-protocol: foxglove.sdk.v1\r\nsec-websocket-accept: x\r\n\r\n";
        let back = rewrite_response(answer);
        assert_eq!(
            back,
            answer.replace(
                "sec-websocket-protocol: foxglove.sdk.v1",
                "Sec-WebSocket-Protocol: foxglove.websocket.v1"
            )
        );
        // A 400 passes unchanged.
        let refused = "HTTP/1.1 400 Bad Request\r\ncontent-length: 3\r\n\r\n";
        assert_eq!(rewrite_response(refused), refused);
    }
}
