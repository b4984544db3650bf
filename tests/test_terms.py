"""Parametrised terms (``newton_lab.task_api.terms``): names resolve to slots, nested terms first, one compiled
function per distinct term, one hold counter per ``held`` term, and every misuse is one line."""

from __future__ import annotations

import dataclasses

import newton_lab.tasks  # noqa: F401  (registers every task id)
import pytest
from newton_lab.tasks.common.terminations import all_of, dropped, grasped, held, lifted

from newton_lab.task_api.cfg import TermCfg, TerminationTermCfg
from newton_lab.task_api.registry import lookup
from newton_lab.task_api.terms import TermResolver, bind, resolve_cfg, term_factory

SCENE = ("table", "cube", "blue_block")

seen: list[dict] = []


@term_factory(entities=("entity", "others"))
def probe(*, entity: int, others: tuple[int, ...] = (), height: float = 0.0):
    """Records what the factory was given (a stand-in: it returns a marker, not a @wp.func)."""
    seen.append({"entity": entity, "others": others, "height": height})
    return ("probe", entity, others, height)


def test_names_become_slots_and_constants_pass_through():
    seen.clear()
    out = TermResolver(SCENE)(probe(entity="blue_block", others=("cube", "table"), height=0.1))
    assert out == ("probe", 2, (1, 0), 0.1) and seen == [{"entity": 2, "others": (1, 0), "height": 0.1}]


def test_one_function_per_distinct_term_and_nested_terms_resolve_first():
    seen.clear()
    r = TermResolver(SCENE)
    a = r(probe(entity="cube", height=0.2))
    assert r(probe(entity="cube", height=0.2)) is a and len(seen) == 1  # same parameters: built once
    assert r(probe(entity="cube", height=0.3)) is not a and len(seen) == 2
    cube_up = lifted(entity="cube", min_z=0.2)
    both = r(all_of(terms=(cube_up, grasped(entity="cube"))))
    assert callable(both) and r(cube_up) is r(lifted(entity="cube", min_z=0.2))


def test_each_held_term_gets_its_own_counter():
    r = TermResolver(SCENE)
    up = lifted(entity="cube", min_z=0.2)
    r(held(term=up, steps=5))
    r(held(term=up, steps=5))  # the same term: the same counter
    r(held(term=up, steps=7))
    r(held(term=grasped(entity="cube"), steps=5))
    assert r.hold_slots == 3


def test_misuse_is_one_line():
    r = TermResolver(SCENE, task="GalbotG1-X-v0")
    cases = [
        (lambda: r(probe(entity="cueb")), "parameter entity='cueb' names no scene object (did you mean cube?)"),
        (lambda: r(probe(entity=1)), "name the object (one of ['table', 'cube', 'blue_block']), not its slot"),
        (lambda: r(probe(entity="cube", colour="red")), "term probe parameters"),
        (lambda: bind(lambda ctx, w: True, {"entity": "cube"}), "is a plain @wp.func"),
        (lambda: probe(entity=["cube", {"a": [1]}], height={1, 2}), "term parameters must be names, numbers"),
    ]
    for make, message in cases:
        with pytest.raises(ValueError) as e:
            make()
        assert message in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_a_task_cfg_resolves_to_plain_functions_once():
    cfg = dataclasses.replace(
        lookup("GalbotG1-PickCube-v0").cfg(),
        task_id="t",
        terminations={"cube_dropped": TerminationTermCfg(func=dropped, params={"entity": "cube", "below_z": 0.05})},
        signals={"grasped_cube": TermCfg(func=grasped(entity="cube"))},
    )
    resolved = resolve_cfg(cfg)
    funcs = [
        resolved.terminations["cube_dropped"].func,
        resolved.signals["grasped_cube"].func,
        *resolved.phase_success,
        *(t.func for t in resolved.rewards.values()),
    ]
    assert all(type(f).__name__ == "Function" for f in funcs)  # Warp functions, parameters baked in
    assert not any(t.params for t in resolved.terminations.values())
    again = resolve_cfg(resolved)
    assert again.terminations["cube_dropped"].func is resolved.terminations["cube_dropped"].func
    assert again.hold_slots == resolved.hold_slots
