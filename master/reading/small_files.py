"""Reading a small input file the user names (a parameter file, a scenario): its size
checked before it is read, its text decoded, each failure one line of bad input; and the
one XML parser for every untrusted XML file (SSD, SSV, scenario)."""
from __future__ import annotations

from pathlib import Path

from dsim.master.errors import InputError


def bounded_size(path: Path, limit: int, what: str) -> int:
    """The size of ``path`` in bytes, refused (InputError) when it cannot be read or
    holds more than ``limit`` bytes (``what``: the kind of file, for the message)."""
    try:
        size = path.stat().st_size
    except OSError as error:
        raise InputError(f"{path}: cannot read: {error.strerror}") from None
    if size > limit:
        raise InputError(f"{path}: {size} bytes: more than {what}'s {limit} bytes")
    return size


def bounded_bytes(path: Path, limit: int, what: str) -> bytes:
    """The bytes of ``path``, refused as :func:`bounded_size` refuses it."""
    bounded_size(path, limit, what)
    try:
        return path.read_bytes()
    except OSError as error:
        raise InputError(f"{path}: cannot read: {error.strerror}") from None


def utf8_text(path: Path, data: bytes) -> str:
    """``data`` (read from ``path``) as text: UTF-8, a byte-order mark dropped."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not UTF-8 text") from None


def untrusted_xml_parser(remove_comments: bool = False):
    """An lxml parser for XML from an untrusted file (an SSD, a parameter set, a
    scenario): no entity resolved (no external file read into a value, no billion
    laughs), no DTD loaded, nothing fetched from the network, no huge tree.  lxml's
    default parser resolves internal entities and loads DTDs."""
    from lxml import etree  # here: a Ray worker reads input tables, and imports no lxml

    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           huge_tree=False, remove_comments=remove_comments)


def parse_untrusted(source, remove_comments: bool = False):
    """The root element of untrusted XML: a file's path (str) or its bytes, parsed with
    :func:`untrusted_xml_parser`.  A document that declares a document type is refused
    (etree.XMLSyntaxError, as malformed XML): with its entities left unread, lxml's
    schema check fails on it with an internal error, and no SSP or scenario file needs
    one."""
    from lxml import etree

    parser = untrusted_xml_parser(remove_comments)
    tree = (etree.fromstring(source, parser).getroottree() if isinstance(source, bytes)
            else etree.parse(source, parser))
    root = tree.getroot()
    if tree.docinfo.internalDTD is not None:
        raise etree.XMLSyntaxError(
            "a document type declaration (DTD) before the root element: DTDs and "
            "entities are not read", 0, root.sourceline or 1, 0)
    return root
