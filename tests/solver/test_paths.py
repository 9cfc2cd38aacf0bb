"""Where the package's data lives (solver/paths.py): the model file a process loads."""

from solver.paths import DEFAULT_MODEL_PATH, model_path


def test_the_model_file_is_the_environment_s_else_the_default(monkeypatch, tmp_path):
    monkeypatch.delenv("HEADRECON_MODEL", raising=False)
    assert model_path() == DEFAULT_MODEL_PATH
    monkeypatch.setenv("HEADRECON_MODEL", str(tmp_path / "other.npz"))
    assert model_path() == tmp_path / "other.npz"
    monkeypatch.setenv("HEADRECON_MODEL", "")  # empty: as if unset
    assert model_path() == DEFAULT_MODEL_PATH
