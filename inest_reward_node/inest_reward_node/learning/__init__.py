"""Offline learning of reward models: pretraining, calibration, stage fitting and the
reward-quality report. It may import the simulator, whose demonstrations and true stages it
learns from; the runtime never imports it.
"""
