"""Options declared once on the configuration's fields (stream.session.options) and generated per command."""

import argparse
from dataclasses import fields

from livedic.stream.cli import build_parser
from livedic.stream.session.config import MeasureConfig, TrackingConfig
from livedic.stream.session.options import add_config_arguments, config_values, flag_of, option_fields


def _flags(parser_args):
    return {action.dest: action for action in parser_args._actions}


def test_every_tracking_setting_is_an_option_and_run_and_replay_take_the_same_ones():
    assert [f.name for f in option_fields(TrackingConfig)] == [f.name for f in fields(TrackingConfig)]
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    run, replay = _flags(commands["run"]), _flags(commands["replay"])
    for f in option_fields(TrackingConfig):
        assert run[f.name].option_strings == replay[f.name].option_strings == [flag_of(f)]
        assert run[f.name].default == f.default           # run: the configuration's default
        assert replay[f.name].default is None              # replay: unset means the recorded value


def test_parsed_options_make_the_configuration_and_its_defaults_round_trip():
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, TrackingConfig)
    assert TrackingConfig(**config_values(TrackingConfig, parser.parse_args([]))) == TrackingConfig()
    args = parser.parse_args(["--subset", "31", "--seed-radius", "3", "--reference-update", "never"])
    config = TrackingConfig(**config_values(TrackingConfig, args))
    assert (config.subset, config.seed_radius, config.reference_update) == (31, 3, "never")


def test_without_defaults_only_the_given_options_are_read():
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, TrackingConfig, with_defaults=False)
    args = parser.parse_args(["--refind-zncc", "0.7"])
    assert config_values(TrackingConfig, args, given_only=True) == {"refind_zncc": 0.7}
    assert set(config_values(TrackingConfig, args)) == {f.name for f in fields(TrackingConfig)}


def test_a_flag_option_and_the_help_name_the_default():
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, MeasureConfig)
    assert parser.parse_args([]).guided is True and parser.parse_args(["--no-guided"]).guided is False
    text = " ".join(parser.format_help().split())
    assert "(default 21)" in text and "(default improved-surface-fit)" in text
