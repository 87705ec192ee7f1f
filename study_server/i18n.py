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

import re
from pathlib import Path

from scenesuggest.errors import SceneSuggestError

TRANSLATIONS = Path(__file__).resolve().parent / "translations"
DOMAIN = "messages"
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
        wanted = placeholders(ids[0])
        for translated in strings:
            if translated and placeholders(translated) != wanted:
                raise CatalogueError(f"the translation of {ids[0]!r} has the placeholders "
                                     f"{sorted(placeholders(translated))}, its source {sorted(wanted)}",
                                     file=str(path), line=message.lineno, field="msgstr")
    return catalog


def compile_catalogues(out: Path) -> Path:
    """Check every shipped catalogue (:func:`check_catalogue`) and compile it into ``out`` (again where its .po is
    newer); returns ``out``, the folder Flask-Babel reads."""
    from babel.messages.mofile import write_mo

    for language in shipped()[1:]:
        source = TRANSLATIONS / language / "LC_MESSAGES" / f"{DOMAIN}.po"
        target = out / language / "LC_MESSAGES" / f"{DOMAIN}.mo"
        catalog = check_catalogue(source)
        if target.exists() and target.stat().st_mtime >= source.stat().st_mtime:
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".part")
        with partial.open("wb") as f:
            write_mo(f, catalog)
        partial.replace(target)
    return out


def page_language() -> str:
    """The language of the page being made: the participant's (set by the participant's routes), else the
    source language."""
    from flask import g

    return g.get("language") or SOURCE


def translated(text) -> str:
    """A study's text in the page's language (the ``tr`` filter of the templates)."""
    return text.in_language(page_language()) if isinstance(text, Text) else text


def choose(study, accept_languages) -> str:
    """The language a new participant of ``study`` sees: the study's only one, or the one of its languages that
    ``accept_languages`` (the request's) prefers, else its default."""
    return accept_languages.best_match(study.languages, default=study.languages[0]) if len(study.languages) > 1 \
        else study.languages[0]


def init_app(app) -> None:
    """Flask-Babel over the compiled catalogues, the language of each page, and the ``tr`` filter."""
    from flask_babel import Babel

    compiled = compile_catalogues(Path(app.instance_path) / "translations")
    app.config["BABEL_TRANSLATION_DIRECTORIES"] = str(compiled)
    Babel(app, locale_selector=page_language, default_locale=SOURCE)
    app.jinja_env.filters["tr"] = translated
    app.jinja_env.globals["page_language"] = page_language
