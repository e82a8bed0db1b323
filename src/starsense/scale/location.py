"""Where a HATS catalogue is: ``hats:`` specifications, published names, URL checks.

Light on purpose (no lsdb, no NumPy): the command line checks a catalogue's address here before
it imports the deep-catalogue stack, so a refused URL or a malformed port is reported at once.
"""

from __future__ import annotations

import time
import urllib.error
import urllib.parse
import urllib.request

from starsense._io import probe_tcp
from starsense.errors import InputError
from starsense.scale.errors import CatalogUnavailableError

__all__ = [
    "PUBLISHED_HATS",
    "URL_SCHEMES",
    "URL_TIMEOUT_S",
    "check_url",
    "hats_location",
    "is_hats_spec",
]

#: published HATS catalogues (module notes)
PUBLISHED_HATS: dict[str, str] = {
    "gaia_dr3": "https://data.lsdb.io/hats/gaia_dr3",
    "two_mass": "https://data.lsdb.io/hats/two_mass",
}

#: seconds to wait for a catalogue URL to answer
URL_TIMEOUT_S = 10.0

#: address prefixes read as a URL (anything else is a local path)
URL_SCHEMES = ("http://", "https://", "s3://", "gs://", "gcs://", "abfs://", "az://", "file://")


def is_hats_spec(spec: str | None) -> bool:
    """Return whether ``spec`` is a ``hats:PATH_OR_URL`` catalogue specification."""
    return isinstance(spec, str) and spec.strip().lower().startswith("hats:")


def hats_location(spec: str) -> str:
    """PATH_OR_URL of ``hats:PATH_OR_URL`` (a known name such as ``hats:gaia_dr3`` -> its URL)."""
    text = spec.strip()
    if text.lower().startswith("hats:"):
        text = text[5:].strip()
    if not text:
        raise InputError(
            "hats: needs a path or URL, e.g. hats:./my_hats or hats:" + PUBLISHED_HATS["gaia_dr3"]
        )
    return PUBLISHED_HATS.get(text, text)


def probe_url(url: str, timeout_s: float) -> None:
    """Fail fast, with a specific error, when a catalogue URL does not answer.

    The address is checked first (a port outside 1-65535 is refused before connecting), then
    one TCP connection says at once whether anything listens (:func:`starsense._io.probe_tcp`),
    then the catalogue's properties file is asked for.
    """
    parts = urllib.parse.urlsplit(url)
    try:
        port = parts.port or (443 if parts.scheme == "https" else 80)
    except ValueError:  # "Port out of range 0-65535", "Port could not be cast to integer"
        raise CatalogUnavailableError(
            f"HATS catalogue {url}: the port is not a number in 1-65535"
        ) from None
    if not parts.hostname:
        raise CatalogUnavailableError(f"HATS catalogue {url}: the URL names no host")
    try:
        probe_tcp(
            parts.hostname, port, timeout_s=timeout_s, what=f"cannot reach HATS catalogue {url}"
        )
    except InputError as exc:
        raise CatalogUnavailableError(str(exc)) from None
    base = url.rstrip("/")
    last = None
    t0 = time.monotonic()
    for leaf in ("collection.properties", "hats.properties", "properties"):
        try:
            with urllib.request.urlopen(f"{base}/{leaf}", timeout=timeout_s) as response:
                if response.status == 200:
                    return
        except urllib.error.HTTPError as exc:  # the server answers: try the next file
            last = exc
            continue
        except (urllib.error.URLError, OSError, ValueError) as exc:
            reason = getattr(exc, "reason", exc)
            waited = (
                f" (no answer after {time.monotonic() - t0:.1f} s)"
                if isinstance(reason, TimeoutError)
                else ""
            )
            raise CatalogUnavailableError(
                f"cannot reach HATS catalogue {url}{waited}: {reason}"
            ) from None
    raise CatalogUnavailableError(
        f"{url} is not a HATS catalogue: no collection.properties, hats.properties or "
        f"properties file ({last})"
    )


def check_url(spec: str, timeout_s: float = URL_TIMEOUT_S) -> None:
    """For a ``hats:`` specification naming an HTTP(S) URL, check it answers; else do nothing.

    Raises
    ------
    CatalogUnavailableError
        A malformed port, a refused connection (at once), no answer within ``timeout_s``, or a
        server without a HATS properties file.
    """
    if not is_hats_spec(spec):
        return
    location = hats_location(spec)
    if location.lower().startswith(("http://", "https://")):
        probe_url(location, timeout_s)
