"""The delayed fit's speed goal is judged only at the size it is for."""

from pipelines.bench.fit_delayed import FIT_DELAYED_GOAL_S, _goal_text, within_goal


def test_the_goal_applies_to_the_full_size_fit_only():
    assert within_goal(84, 4, 1000, FIT_DELAYED_GOAL_S - 1) is True
    assert within_goal(84, 4, 1000, FIT_DELAYED_GOAL_S + 1) is False
    # 12 subjects, or fewer chains or draws, fast or slow: no verdict either way.
    for size in ((24, 4, 1000), (84, 2, 1000), (84, 4, 300)):
        assert within_goal(*size, 10.0) is None and within_goal(*size, 1e6) is None
    text = _goal_text({"goal_s": FIT_DELAYED_GOAL_S, "within_goal": None})
    assert "not this size" in text and "met" not in text
    assert _goal_text({"goal_s": FIT_DELAYED_GOAL_S, "within_goal": False}).endswith("NOT met")
