"""tudorvision.rgbd"""
__all__: list[str] = []
