"""tudorvision.stereo"""
__all__: list[str] = []
