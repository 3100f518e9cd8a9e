from __future__ import annotations

from django.contrib import admin

from .models import Building, EnvironmentalTag, Membership, SubMap, TopologyEdge


class MembershipInline(admin.TabularInline[Membership, Building]):
    model = Membership
    extra = 1
    autocomplete_fields = ["user"]


@admin.register(Building)
class BuildingAdmin(admin.ModelAdmin[Building]):
    list_display = ["code", "name", "zip_code"]
    inlines = [MembershipInline]


@admin.register(SubMap)
class SubMapAdmin(admin.ModelAdmin[SubMap]):
    list_display = ["building", "code", "name", "width", "height", "resolution", "mode"]
    list_filter = ["building"]
    exclude = ["image"]
    readonly_fields = ["version", "width", "height", "image_name"]


@admin.register(EnvironmentalTag)
class EnvironmentalTagAdmin(admin.ModelAdmin[EnvironmentalTag]):
    list_display = ["building", "marker_id", "submap", "links_to", "x", "y", "yaw"]
    list_filter = ["building"]


@admin.register(TopologyEdge)
class TopologyEdgeAdmin(admin.ModelAdmin[TopologyEdge]):
    list_display = ["building", "a", "b", "cost"]
