"""bench/rendered_heads.py: the options for the rendered heads the photos-only benchmarks
fit (bench_corrections', bench_photo_size's and bench_photo_variants')."""

import argparse

from bench.rendered_heads import TEN_HEADS, add_head_options


def test_the_head_options_default_to_the_sample_and_the_ten_heads():
    parser = argparse.ArgumentParser()
    add_head_options(parser)
    args = parser.parse_args([])
    assert args.heads is None and args.render == TEN_HEADS == [101, *range(201, 209)]
    args = parser.parse_args(["--heads", "a", "b", "--render"])
    assert args.heads == ["a", "b"] and args.render == []
    parser = argparse.ArgumentParser()
    add_head_options(parser, render=[])
    assert parser.parse_args([]).render == []
