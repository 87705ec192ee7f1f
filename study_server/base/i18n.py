"""Participants in their own language.

Two kinds of text reach a participant. The server's own — the pages' templates, the editor's strings (sent to the
page as JSON: the client has no catalogue of its own), the survey's errors, the messages of the ways out — are
written in English and translated by the gettext catalogue of each language, through Flask-Babel
(``study_server/translations/<language>/LC_MESSAGES/messages.po``; compiled into the instance folder when the app
starts, after a check that names the file, line and message of any broken placeholder). A study's own texts —
title, consent, instructions, survey items, conditions, scene titles — are given per language in the study file
(:class:`Text`).

A study speaks ``languages`` (the first is its default) or one ``language``; a participant sees the study's only
language, or the one of its languages their browser prefers (``Accept-Language``), chosen at arrival and kept
(``participants.language``, exported).
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

from scenesuggest.errors import SceneSuggestError

TRANSLATIONS = Path(__file__).resolve().parents[1] / "translations"
DOMAIN = "messages"
#: The names of a corpus's categories in other languages (``<language>/LC_MESSAGES/categories.po``: msgid the
#: category, msgstr its name), read as they are: they are data of the corpus, not strings of the code.
CATEGORIES = "categories"
#: The language the server's strings are written in (it needs no catalogue).
SOURCE = "en"
#: A placeholder of the editor's strings (``{n}``) or of a Python format (``%(n)s``, ``{n}``).
_BRACES = re.compile(r"\{[A-Za-z_][A-Za-z0-9_]*\}")
_PERCENT = re.compile(r"%\([A-Za-z_][A-Za-z0-9_]*\)[sd]")


class CatalogueError(SceneSuggestError):
    """A message catalogue the server cannot use (a broken placeholder, a file that does not parse)."""


def shipped() -> tuple[str, ...]:
    """The languages this server speaks: its source language and every language it has a catalogue of."""
    found = sorted(p.parent.parent.name for p in TRANSLATIONS.glob(f"*/LC_MESSAGES/{DOMAIN}.po"))
    return (SOURCE, *[lang for lang in found if lang != SOURCE])


class Text(str):
    """A study's text: the string itself in the study's default language, and its translations by language."""

    translations: dict[str, str]

    def __new__(cls, default: str, translations: dict[str, str] | None = None):
        text = super().__new__(cls, default)
        text.translations = dict(translations or {})
        return text

    def in_language(self, language: str | None) -> str:
        """The text in ``language`` (the default where it has no translation)."""
        return self.translations.get(language or "", str(self))


def placeholders(text: str) -> set[str]:
    return set(_BRACES.findall(text)) | set(_PERCENT.findall(text))


def check_catalogue(path: Path):
    """Read the catalogue at ``path`` (a .po file); a message whose translation has other placeholders than its
    source, or a file that does not parse, is a :class:`CatalogueError` naming the file, the line and the
    message."""
    from babel.messages.pofile import PoFileError, read_po

    try:
        with path.open("rb") as f:
            catalog = read_po(f, abort_invalid=True)
    except (PoFileError, UnicodeDecodeError) as e:
        raise CatalogueError(f"not a readable catalogue ({e})", file=str(path)) from None
    for message in catalog:
        if not message.id or not message.string:
            continue
        ids = message.id if isinstance(message.id, tuple) else (message.id,)
        strings = message.string if isinstance(message.string, tuple) else (message.string,)
        wanted = set().union(*(placeholders(i) for i in ids))
        for translated in strings:
            found = placeholders(translated)
            # a plural form may leave out the count its source names (German "ein Objekt"); no form adds one
            if translated and (found != wanted if len(ids) == 1 else not found <= wanted):
                raise CatalogueError(f"the translation of {ids[0]!r} has the placeholders {sorted(found)}, its "
                                     f"source {sorted(wanted)}", file=str(path), line=message.lineno,
                                     field="msgstr")
            try:  # the pages format every translation with its named values: a lone % would break the page
                translated % {name[2:-2]: "" for name in _PERCENT.findall(translated)}
            except (ValueError, TypeError, KeyError) as e:
                raise CatalogueError(f"the translation of {ids[0]!r} cannot be formatted ({e}): write a % as %%",
                                     file=str(path), line=message.lineno, field="msgstr") from None
    return catalog


def compile_catalogues(out: Path) -> Path:
    """Check every shipped catalogue (:func:`check_catalogue`) and compile it into ``out`` where what is there
    differs (by content: a catalogue copied with an older time is compiled too); returns ``out``, the folder
    Flask-Babel reads. Several processes may start at once: each writes a file of its own and renames it into
    place, so a reader sees one whole catalogue or another."""
    import io
    import os
    import secrets

    from babel.messages.mofile import write_mo

    for language in shipped()[1:]:
        source = TRANSLATIONS / language / "LC_MESSAGES" / f"{DOMAIN}.po"
        target = out / language / "LC_MESSAGES" / f"{DOMAIN}.mo"
        compiled = io.BytesIO()
        write_mo(compiled, check_catalogue(source))
        if target.exists() and target.read_bytes() == compiled.getvalue():
            continue
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            partial = target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}")
            partial.write_bytes(compiled.getvalue())
            os.replace(partial, target)
        except OSError as e:
            raise CatalogueError(f"cannot write the compiled catalogue ({e.strerror}): the instance folder must "
                                 "be writable", file=str(target)) from None
    return out


@functools.cache
def category_names(language: str) -> dict[str, str]:
    """Category → its name in ``language`` (checked as any catalogue; empty where none is shipped)."""
    path = TRANSLATIONS / language / "LC_MESSAGES" / f"{CATEGORIES}.po"
    if language == SOURCE or not path.exists():
        return {}
    return {m.id: m.string for m in check_catalogue(path) if m.id and m.string}


def category_label(category: str, language: str | None) -> str | None:
    """A category's name in ``language``, None where it has none (the page then words the category itself)."""
    return category_names(language or SOURCE).get(category)


def page_language() -> str:
    """The language of the page being made: the participant's (set by the participant's routes); on another
    participant page (one that no route matched), the one of the server's languages the browser prefers; else the
    source language (the admin's pages)."""
    from flask import g, has_request_context, request

    if g.get("language"):
        return g.language
    if has_request_context() and request.path.startswith("/study/"):
        return preferred(shipped(), request.accept_languages, SOURCE)
    return SOURCE


def translated(text) -> str:
    """A study's text in the page's language (the ``tr`` filter of the templates)."""
    return text.in_language(page_language()) if isinstance(text, Text) else text


def preferred(offered, accept_languages, default: str) -> str:
    """The language of ``offered`` that ``accept_languages`` (a request's) prefers: its entries by quality (0: not
    wanted), each matched exactly, else by its primary language (``de-CH`` → ``de``); ``default`` when none is
    offered."""
    for tag, quality in sorted(accept_languages, key=lambda entry: -entry[1]):
        if quality <= 0:
            continue
        tag = tag.lower()
        for candidate in (tag, tag.split("-")[0]):
            if candidate in offered:
                return candidate
    return default


def choose(study, accept_languages) -> str:
    """The language a new participant of ``study`` sees: the study's only one, or the one of its languages that
    ``accept_languages`` (the request's) prefers, else its default."""
    return preferred(study.languages, accept_languages, study.languages[0])


def init_app(app) -> None:
    """Flask-Babel over the compiled catalogues, the language of each page, and the ``tr`` filter."""
    from flask_babel import Babel

    compiled = compile_catalogues(Path(app.instance_path) / "translations")
    for language in shipped():  # a broken category catalogue stops the start-up too, naming its file and line
        category_names(language)
    app.config["BABEL_TRANSLATION_DIRECTORIES"] = str(compiled)
    Babel(app, locale_selector=page_language, default_locale=SOURCE)
    app.jinja_env.filters["tr"] = translated
    app.jinja_env.globals["page_language"] = page_language
