"""bench/rendered_heads.py: the options for the rendered heads the photos-only benchmarks
fit (bench_corrections', bench_photo_size's and bench_photo_variants')."""

import argparse

from bench.rendered_heads import (
    ROOT,
    TEN_HEADS,
    add_head_options,
    chosen_folders,
    head_folders,
    photo_path,
)


def test_the_head_options_default_to_the_sample_and_the_ten_heads():
    parser = argparse.ArgumentParser()
    add_head_options(parser)
    args = parser.parse_args([])
    assert args.heads is None and args.render == TEN_HEADS == [101, *range(201, 209)]
    assert args.skin == "light" and args.expression is None and args.pitch == 0.0
    assert args.light == "studio"
    args = parser.parse_args(["--heads", "a", "b", "--render"])
    assert args.heads == ["a", "b"] and args.render == []
    parser = argparse.ArgumentParser()
    add_head_options(parser, render=[])
    assert parser.parse_args([]).render == []


def test_heads_of_another_skin_tone_are_the_sample_s_seed_and_the_others_in_their_folders(
        monkeypatch):
    import bench.rendered_heads as rendered

    made = []
    monkeypatch.setattr(rendered, "render_head", lambda *a: made.append(a))
    heads = ROOT / "generated" / "bench_heads"
    assert head_folders(None, [101]) == [ROOT / "generated" / "sample", heads / "seed101"]
    assert head_folders(None, [101], "dark") == [heads / "seed7_dark", heads / "seed101_dark"]
    assert made[-2:] == [(7, heads / "seed7_dark", "dark", None, 0.0, "studio"),
                         (101, heads / "seed101_dark", "dark", None, 0.0, "studio")]
    # a face with an expression: the sample's seed rendered so too, the tone before it
    assert head_folders(None, [101], "light", "smile") == [heads / "seed7_smile",
                                                           heads / "seed101_smile"]
    assert made[-1] == (101, heads / "seed101_smile", "light", "smile", 0.0, "studio")
    assert head_folders(None, [], "dark", "jaw_open") == [heads / "seed7_dark_jaw_open"]
    # a nodded head: its pitch last in the folder's name, up (negative) told from down
    assert head_folders(None, [101], "light", None, -10.0) == [heads / "seed7_pitch-10",
                                                               heads / "seed101_pitch-10"]
    assert made[-1] == (101, heads / "seed101_pitch-10", "light", None, -10.0, "studio")
    assert head_folders(None, [], "dark", "smile", 7.5) == [heads / "seed7_dark_smile_pitch7.5"]
    # another light: last in the folder's name
    assert head_folders(None, [101], "light", None, 0.0, "window") == [
        heads / "seed7_window", heads / "seed101_window"]
    assert made[-1] == (101, heads / "seed101_window", "light", None, 0.0, "window")
    assert head_folders(None, [], "dark", None, 5.0, "window") == [
        heads / "seed7_dark_pitch5_window"]
    # folders given are taken as they are, before the seeds'
    assert head_folders(["x"], [], "dark") == [rendered.Path("x")]


def test_the_chosen_folders_are_those_the_options_name(monkeypatch):
    import bench.rendered_heads as rendered

    monkeypatch.setattr(rendered, "render_head", lambda *a: None)
    parser = argparse.ArgumentParser()
    add_head_options(parser)
    args = parser.parse_args(["--render", "101", "--expression", "eyes_closed"])
    heads = ROOT / "generated" / "bench_heads"
    assert chosen_folders(args) == [heads / "seed7_eyes_closed", heads / "seed101_eyes_closed"]
    args = parser.parse_args(["--render", "101", "--pitch", "12"])
    assert chosen_folders(args) == [heads / "seed7_pitch12", heads / "seed101_pitch12"]
    args = parser.parse_args(["--render", "101", "--light", "window"])
    assert chosen_folders(args) == [heads / "seed7_window", heads / "seed101_window"]


def test_a_folder_s_photo_is_its_jpeg_with_the_lens_else_its_png(tmp_path):
    (tmp_path / "front.png").write_bytes(b"")
    assert photo_path(tmp_path, "front") == tmp_path / "front.png"
    (tmp_path / "front.jpg").write_bytes(b"")  # tools.make_sample --lens writes JPEGs
    assert photo_path(tmp_path, "front") == tmp_path / "front.jpg"
    assert photo_path(tmp_path, "side") == tmp_path / "side.png"
