//! The host a served web viewer's address names, so the printed URL opens where it is
//! read: `--advertise HOST` when given; the bound address when it is one a browser can
//! reach; and for an address bound to every interface (`0.0.0.0`, `::`), this machine's
//! own address rather than the unspecified one, which no other machine can open.

use std::net::{IpAddr, Ipv4Addr, UdpSocket};

use anyhow::{bail, Result};

/// The host to put in the printed URLs: `advertise`, else `bind`, else (for an
/// unspecified `bind`) this machine's address.
pub fn host(bind: &str, advertise: Option<&str>) -> Result<String> {
    if let Some(host) = advertise {
        if host.is_empty() || host.contains(['/', ' ', '?', '#']) {
            bail!("--advertise takes a host name or address (e.g. 10.0.0.5 or viewer.lan), not `{host}`");
        }
        return Ok(bracketed(host));
    }
    match bind.parse::<IpAddr>() {
        Ok(ip) if ip.is_unspecified() => match machine_address() {
            Some(ip) => Ok(bracketed(&ip.to_string())),
            None => {
                tracing::warn!(
                    "--bind {bind}: this machine has no address but loopback; the printed \
                     address names 127.0.0.1 (give --advertise HOST for another machine)"
                );
                Ok(Ipv4Addr::LOCALHOST.to_string())
            }
        },
        _ => Ok(bracketed(bind)),
    }
}

/// An IPv6 address in a URL goes in brackets.
fn bracketed(host: &str) -> String {
    match host.parse::<IpAddr>() {
        Ok(IpAddr::V6(_)) => format!("[{host}]"),
        _ => host.to_string(),
    }
}

/// This machine's address as others see it: the source address of its default route
/// (found by connecting a UDP socket, which sends nothing), else the first IPv4 address
/// of an interface that is up and not loopback.
pub fn machine_address() -> Option<IpAddr> {
    let routed = UdpSocket::bind((Ipv4Addr::UNSPECIFIED, 0))
        .and_then(|socket| {
            // TEST-NET-1: never answered, only routed.
            socket.connect((Ipv4Addr::new(192, 0, 2, 1), 9))?;
            socket.local_addr()
        })
        .map(|addr| addr.ip())
        .ok()
        .filter(|ip| !ip.is_loopback() && !ip.is_unspecified());
    routed.or_else(|| {
        pnet_datalink::interfaces()
            .into_iter()
            .filter(|i| i.is_up() && !i.is_loopback())
            .flat_map(|i| i.ips)
            .map(|net| net.ip())
            .find(|ip| ip.is_ipv4() && !ip.is_loopback())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_given_host_is_kept_and_a_bound_one_named() {
        assert_eq!(host("0.0.0.0", Some("viewer.lan")).unwrap(), "viewer.lan");
        assert_eq!(host("127.0.0.1", None).unwrap(), "127.0.0.1");
        assert_eq!(host("::1", None).unwrap(), "[::1]");
        assert!(host("0.0.0.0", Some("http://x/")).is_err());
        let unspecified = host("0.0.0.0", None).unwrap();
        assert_ne!(unspecified, "0.0.0.0");
    }
}
