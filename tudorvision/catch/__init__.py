"""tudorvision.catch"""
__all__: list[str] = []
