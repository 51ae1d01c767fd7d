"""Which text encoding a table's bytes are in: UTF-8, GB18030 or Latin-1.

Spreadsheets and historians save CSV files in the machine's code page: Chinese names of
columns and buses in GB18030 (GBK), Western ones (``Spannung_µ``, ``Leistung_é``) in
Latin-1 / Windows-1252. The numbers are ASCII in all of them; only the header and the
text columns (a fleet's bus names) differ. The same order as the COMTRADE ``.cfg``
reader's: UTF-8 when the bytes are valid UTF-8, GB18030 when they decode as it, hold
CJK characters and every character is bytes of 0x80 and above, else Latin-1 (which
decodes any byte).
"""

from __future__ import annotations

import codecs

__all__ = ["ENCODINGS", "SNIFF_BYTES", "detect_encoding", "has_cjk"]

#: The encodings tried, in turn.
ENCODINGS = ("utf-8", "gb18030", "latin-1")
#: How much of a file is looked at (the header and the first rows).
SNIFF_BYTES = 1 << 20


def has_cjk(text: str) -> bool:
    """True when ``text`` holds CJK ideographs or CJK punctuation."""
    return any("\u4e00" <= ch <= "\u9fff" or "\u3000" <= ch <= "\u303f" for ch in text)


def detect_encoding(sample: bytes, *, complete: bool) -> str:
    """The encoding of ``sample``: ``"utf-8"``, ``"gb18030"`` or ``"latin-1"``.

    Parameters
    ----------
    sample : bytes
        The first bytes of the file (its header, and the rows after it).
    complete : bool
        Whether ``sample`` is the whole file. When it is not, a character cut at its end
        is not held against an encoding.

    Returns
    -------
    str
        A Python codec name.
    """
    for enc in ("utf-8-sig", "gb18030"):
        decoder = codecs.getincrementaldecoder(enc)()
        try:
            text = decoder.decode(sample, final=complete)
        except UnicodeDecodeError:
            continue
        if enc == "utf-8-sig":
            return "utf-8"
        if has_cjk(text) and _double_byte(text):
            return "gb18030"
    return "latin-1"


def _double_byte(text: str) -> bool:
    # Chinese text in GB18030 is pairs of bytes of 0x81 and above. Latin-1 text decodes
    # as GB18030 too when an accented letter is followed by an ASCII one ('ü' 's' ->
    # 0xFC 0x73, an ideograph): a byte under 0x80 inside a character says Latin-1.
    return all(min(ch.encode("gb18030")) >= 0x80 for ch in set(text) if ord(ch) >= 0x80)
