"""tudorvision.joint"""
__all__: list[str] = []
