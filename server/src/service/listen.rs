//! The address `--listen` names: an IP address and port, or a host name and port
//! resolved once at startup.

use std::net::{SocketAddr, ToSocketAddrs};

/// The socket address `text` names: `IP:PORT` (`127.0.0.1:50051`, `[::1]:50051`)
/// as written, or `HOST:PORT` (`localhost:50051`) resolved by the system's
/// resolver, listening on the first address it gives. Anything else is an error
/// that says which forms are meant.
pub fn listen_address(text: &str) -> Result<SocketAddr, String> {
    if let Ok(addr) = text.parse() {
        return Ok(addr);
    }
    let forms = "an IP address and port (127.0.0.1:50051, [::1]:50051, 0.0.0.0:50051) \
                 or a host name and port (localhost:50051)";
    let Some((host, port)) = text.rsplit_once(':') else {
        return Err(format!("no port: give {forms}"));
    };
    if host.is_empty() || port.parse::<u16>().is_err() {
        return Err(format!("not an address and port: give {forms}"));
    }
    match text.to_socket_addrs() {
        Ok(mut addrs) => addrs
            .next()
            .ok_or_else(|| format!("the host name `{host}` resolves to no address")),
        Err(e) => Err(format!(
            "the host name `{host}` does not resolve ({e}): give {forms}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_are_read_and_localhost_is_a_loopback_address() {
        assert_eq!(
            listen_address("127.0.0.1:50051"),
            Ok("127.0.0.1:50051".parse().unwrap())
        );
        assert_eq!(listen_address("[::1]:7"), Ok("[::1]:7".parse().unwrap()));
        let local = listen_address("localhost:50051").unwrap();
        assert!(local.ip().is_loopback(), "{local}");
        assert_eq!(local.port(), 50051);
    }

    #[test]
    fn what_is_not_an_address_and_port_says_which_forms_are_meant() {
        for bad in [
            "localhost",
            "127.0.0.1",
            ":50051",
            "localhost:99999",
            "a:b",
            "",
        ] {
            let e = listen_address(bad).unwrap_err();
            assert!(e.contains("localhost:50051"), "{bad}: {e}");
        }
    }
}
