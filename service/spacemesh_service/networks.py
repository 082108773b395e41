"""Client networks (``--trusted-proxies``) and the error of an unusable protection setting.

Below both :mod:`spacemesh_service.settings` (which checks ``trusted_proxies`` when the
settings are made) and :mod:`spacemesh_service.security` (which uses the networks), so
neither imports the other.
"""

from __future__ import annotations

import ipaddress

Network = ipaddress.IPv4Network | ipaddress.IPv6Network


class ConfigError(ValueError):
    """A protection setting cannot be used (an empty key file, a bad CIDR...)."""


def parse_networks(text: str) -> tuple[Network, ...]:
    """``"10.0.0.0/8, 127.0.0.1"`` -> networks.

    Raises
    ------
    ConfigError
        An entry is not an address or CIDR (the message names it).
    """
    networks = []
    for item in text.replace(";", ",").split(","):
        item = item.strip()
        if not item:
            continue
        try:
            networks.append(ipaddress.ip_network(item, strict=False))
        except ValueError:
            raise ConfigError(f"{item!r} is not an IP address or CIDR") from None
    return tuple(networks)
