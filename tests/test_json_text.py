"""The database's JSON text (orjson, json where orjson cannot): what goes in comes back."""

import json
import math

import numpy as np
import pytest

from study_server.base.extensions import json_text, json_value


@pytest.mark.parametrize("value", [
    {"transform": [0.1, 1e-7, 1e16, -0.0, 5.0, 1 / 3, 2.0**-1074, 1.7976931348623157e308], "id": "sofa 🛋"},
    {"text": "quote \" backslash \\ tab \t é", "nested": [[[]], {}], "none": None, "yes": True},
    {"big": 2**64 - 1, "small": -(2**63)},
])
def test_values_come_back_equal(value):
    text = json_text(value)
    assert json_value(text) == value
    assert json.loads(text) == value  # standard JSON: json reads it too


def test_what_orjson_cannot_write_is_written_by_json():
    assert json.loads(json_text({"huge": 10**30})) == {"huge": 10**30}  # written exactly
    assert json_value(json_text({"huge": 10**30})) == {"huge": 1e30}  # read back as the nearest double
    assert json_text({1: "a", 2.5: "b"}) == '{"1":"a","2.5":"b"}'  # keys that are not text become text, as in json
    assert json_value(json_text({"x": np.float32(0.5), "n": np.int64(3), "a": np.arange(2)})) == {
        "x": 0.5, "n": 3, "a": [0, 1]}
    assert json_text({"nan": float("nan")}) == '{"nan":null}'  # standard JSON, where json would write NaN


def test_text_json_wrote_that_orjson_refuses_is_read_by_json():
    old = json.dumps({"score": float("nan"), "up": float("inf")})  # as stored before: 'NaN', 'Infinity'
    value = json_value(old)
    assert math.isnan(value["score"]) and value["up"] == math.inf
    assert json_value(b'"\\ud800"') == "\ud800"  # a lone surrogate: json's value (the API refuses it by name)
    with pytest.raises(ValueError):
        json_value(b'{"a": ')
    with pytest.raises(RecursionError):
        json_value(b"[" * 100_000 + b"]" * 100_000)


def test_the_apps_answers_are_orjsons_and_flasks_where_orjson_cannot(tmp_path):
    """The app's answers (jsonify) are orjson's text: keys in the order made, NaN as null, UTF-8; dates as Flask
    writes them, an integer past 64 bits exactly (Flask's json); the templates' JSON stays Flask's."""
    from datetime import UTC, datetime

    from flask import Flask

    from study_server.base.extensions import Answers

    app = Flask(__name__)
    app.json = Answers(app)

    def answered(value) -> bytes:
        response = app.json.response(value)
        assert response.mimetype == "application/json"
        return response.get_data()

    with app.app_context():
        assert answered({"b": 1, "a": [0.5, float("nan")], "t": "é"}) == '{"b":1,"a":[0.5,null],"t":"é"}\n'.encode()
        when = datetime(2026, 12, 4, 8, 0, tzinfo=UTC)
        assert json.loads(answered({"at": when})) == {"at": "Fri, 04 Dec 2026 08:00:00 GMT"}
        assert json.loads(answered({"huge": 10**30})) == {"huge": 10**30}
        assert app.json.dumps({"b": 1, "a": 2}) == '{"a": 2, "b": 1}'  # the templates' tojson: Flask's own
        app.debug = True
        assert answered({"b": 1, "a": 2}) == b'{\n  "a": 2,\n  "b": 1\n}\n'  # indented by Flask in debug mode
