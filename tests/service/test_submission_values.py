"""Submitted jobs whose values could not run are refused at submission, and every refusal
is small whatever was sent: a bad seed, more actors than the cluster's CPUs, an integer
too long to convert; a megabyte of unknown keys answered in a few kilobytes, through
``prepare_submission`` and through the REST API (a real app and store)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient
from gaitforge.service.api import create_app
from gaitforge.service.api.problems import MAX_FIELD_ERRORS, FieldError, bounded_errors
from gaitforge.service.jobs.runner import JobRunner
from gaitforge.service.jobs.spec import SubmissionError, prepare_submission
from gaitforge.service.settings import ServiceSettings
from gaitforge.service.store import open_store
from gaitforge.workers.spec_io import MAX_PROBLEMS

from tests.service.api_support import TOKENS, auth

STAGES = [{"scene": "stand-2d", "env_steps": 1000}]
MEGABYTE_OF_UNKNOWN_KEYS = {f"unknown{i:05d}": "x" * 950 for i in range(1000)}
"""about 1 MB of JSON: a thousand keys the schema does not have, each with a long value"""


def _refused(spec: dict | str, **kwargs: object) -> SubmissionError:
    with pytest.raises(SubmissionError) as caught:
        prepare_submission(spec, **kwargs)
    return caught.value


@pytest.mark.parametrize(
    ("seed", "problem"),
    [
        (-1, "Input should be greater than or equal to 0 (got -1)"),
        (2**70, "Input should be less than 4294967296 (got 1180591620717411303424)"),
        (True, "Input should be a valid integer (got True)"),
    ],
)
def test_a_bad_seed_is_refused(seed: object, problem: str) -> None:
    error = _refused({"name": "seeded", "seed": seed, "stages": STAGES})
    assert error.errors == [("seed", problem)]


def test_more_workers_than_the_cluster_has_cpus_are_refused() -> None:
    spec = {"name": "many", "workers": {"num_workers": 3}, "stages": STAGES}
    error = _refused(spec, max_num_workers=2)
    assert error.field == "workers.num_workers"
    assert error.errors[0][1] == (
        "3 rollout actors need 3 CPUs (one each); the cluster has 2: at most 2 (or leave it "
        "out: the cluster's CPUs less one)"
    )
    assert prepare_submission(spec, max_num_workers=3)["workers"]["num_workers"] == 3
    assert prepare_submission(spec)["workers"]["num_workers"] == 3, "None: not checked"


def test_an_integer_too_long_to_convert_is_refused_not_a_crash() -> None:
    error = _refused("name: long\nseed: " + "9" * 5000 + "\nstages: []\n")
    assert error.field == "<root>"
    assert "not valid YAML or JSON: Exceeds the limit" in str(error)


def test_a_megabyte_of_unknown_keys_is_a_short_error() -> None:
    text = json.dumps({"name": "big", "stages": STAGES, **MEGABYTE_OF_UNKNOWN_KEYS})
    assert 900_000 < len(text) < 1_000_000
    error = _refused(text)
    assert len(error.errors) == MAX_PROBLEMS + 1
    assert error.errors[-1] == ("<root>", f"{1000 - MAX_PROBLEMS} more problems not listed")
    assert len(str(error)) < 10_000


def test_a_long_scene_name_is_quoted_only_in_part() -> None:
    error = _refused({"name": "long", "stages": [{"scene": "s/" * 200_000, "env_steps": 1}]})
    assert error.field == "stages.0.scene"
    assert len(str(error)) < 1000


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory, ray_connection) -> Iterator[TestClient]:
    """The app on a real store; the runner is real but not started (nothing runs)."""
    settings = ServiceSettings(home=tmp_path_factory.mktemp("api-values"), tokens=TOKENS)
    store = open_store(settings.db_url)
    with TestClient(create_app(settings, JobRunner(settings, store, ray_connection))) as client:
        yield client
    store.close()


def test_the_api_answers_a_megabyte_of_unknown_keys_in_a_few_kilobytes(
    client: TestClient,
) -> None:
    body = json.dumps({"name": "big", "stages": STAGES, **MEGABYTE_OF_UNKNOWN_KEYS})
    r = client.post(
        "/v1/jobs", content=body, headers={**auth(), "Content-Type": "application/json"}
    )
    assert r.status_code == 422, r.text[:500]
    assert len(r.content) < 20_000
    problem = r.json()
    assert len(problem["errors"]) == MAX_PROBLEMS + 1
    assert problem["errors"][0]["field"] == "unknown00000"
    assert problem["errors"][-1] == {
        "field": "body",
        "message": f"{1000 - MAX_PROBLEMS} more problems not listed",
    }


def test_any_problem_lists_a_bounded_number_of_short_field_errors() -> None:
    errors = [FieldError(field="f" * 1000, message="m" * 100_000) for _ in range(1000)]
    kept = bounded_errors(errors)
    assert len(kept) == MAX_FIELD_ERRORS + 1
    assert kept[-1] == FieldError(
        field="body", message=f"{1000 - MAX_FIELD_ERRORS} more problems not listed"
    )
    assert all(len(e.field) < 300 and len(e.message) < 3000 for e in kept)


def test_a_composed_scene_and_its_scene_set_are_accepted_as_data() -> None:
    stages = [{"scene": "run-2d+clock", "scene_set": {"task.target_speed": 2.5}, "env_steps": 10}]
    job = prepare_submission({"name": "composed", "stages": stages})
    assert job["stages"][0]["scene"] == "run-2d+clock"
    assert job["stages"][0]["scene_set"] == {"task.target_speed": 2.5}


@pytest.mark.parametrize(
    ("scene_set", "field", "problem"),
    [
        (
            {"fault": {"abort_prob": 1.0}},
            "stages.0.scene_set",
            "fault injection is a test hook",
        ),
        ({"body": "../../etc/model"}, "stages.0.scene_set", "body '../../etc/model': unknown"),
        ({"task.targt_speed": 1}, "stages.0.scene_set", "task.targt_speed: Extra inputs"),
    ],
)
def test_a_scene_set_may_not_bring_in_paths_faults_or_unknown_fields(
    scene_set: dict, field: str, problem: str
) -> None:
    stages = [{"scene": "walk-2d", "scene_set": scene_set, "env_steps": 10}]
    error = _refused({"name": "sneaky", "stages": stages})
    assert any(f == field and problem in p for f, p in error.errors), error.errors


def test_an_inline_scene_with_a_scene_set_is_checked_as_composed() -> None:
    task = {"kind": "locomotion", "min_pelvis_height": 0.6}
    inline = {"name": "mine", "body": "gait2d", "task": task}
    stages = [{"scene": inline, "scene_set": {"fault": {"nan_prob": 0.5}}, "env_steps": 10}]
    error = _refused({"name": "sneaky", "stages": stages})
    assert error.field == "stages.0.scene_set", error.errors
    assert "fault injection is a test hook" in error.errors[0][1]
